"""A simulated robot's implementations behind ROS 2 are the bridge's own RosAction nodes on
its servers, named in its namespace of the scenario's ``ros`` block, and it bids for them
only while those servers are in the ROS graph (real rclpy nodes)."""

from __future__ import annotations

from collections.abc import Callable

import anyio
import numpy as np
import pytest
from simserving import serving

from btcap.actors import Clock
from btcap.bt.tree import Tree
from btcap.sim.mission.capabilities import robot_setup
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.model import paper_team
from btcap.sim.world.store import MissionState

pytestmark = pytest.mark.ros


async def _until(holds: Callable[[], bool]) -> None:
    """Until ``holds()``: the ROS graph as rclpy sees it, which signals no event."""
    while not holds():  # noqa: ASYNC110
        await anyio.sleep(0.05)


async def test_implementations_are_rosaction_nodes_bidding_while_their_servers_are_up(
    ros_domain: int,
) -> None:
    from btcap.ros.loader import load

    load()
    from btcap.ros import RosAction, RosBridge, Server, servers_of, with_ros
    from btcap.sim.ros2.names import NAVIGATE_TYPE, OPERATE_TYPE
    from btcap.sim.ros2.steps import CellPose, RosDrive

    ros = ScenarioRos(domain_id=ros_domain, namespace="/team/{robot}")
    grid = load_scenario(builtin_scenarios()["full-team"]).grid()
    husky = paper_team()["husky"]
    state = MissionState.scatter(grid, 2, 0.5, np.random.default_rng(1))
    manager = SimulationManager(state, SimConfig(failure_chance=0.0))
    manager.add_robot("husky1", husky)
    clock = Clock(100.0)
    here = {"goal": grid.start}
    with anyio.fail_after(60):
        async with RosBridge(ros.settings("husky1"), robot="husky1") as bridge:
            setup = robot_setup("husky1", husky, grid, drive=RosDrive(bridge, grid.cell_size_m))
            impls = {i.interface.name: with_ros(i, bridge) for i in setup.implementations}
            explore = impls["Explore"]
            tree = explore.build()
            assert isinstance(tree, Tree)
            kinds = [type(n).__name__ for n in tree.nodes()]
            assert kinds.count(RosAction.__name__) == 2, kinds
            assert CellPose.__name__ in kinds, kinds
            assert servers_of(tree) == [
                Server("action", NAVIGATE_TYPE, "navigate_to_pose"),
                Server("action", OPERATE_TYPE, "explore"),
            ]
            navigate = bridge.action_client(NAVIGATE_TYPE, "navigate_to_pose")
            assert navigate._action_name == "/team/husky1/navigate_to_pose"
            assert explore.bid(here) is None  # nobody serves husky1 yet
            async with serving(manager, {"husky1": husky}, grid, clock, ros=ros):
                await _until(lambda: explore.bid(here) is not None)
                assert explore.bid(here) == husky.operation("explore").duration_s
            # Its servers left the graph (destroyed as they close): it bids no more.
            await _until(lambda: explore.bid(here) is None)
