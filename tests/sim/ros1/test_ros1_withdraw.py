"""A robot that fails or leaves a scenario behind ROS 1 takes its servers out of the ROS
graph, as a real robot would, and gets them back when it recovers or joins again: the
host's ``fail``/``leave``/``recover``/``start`` (what a scenario's events call), seen by
the robot's own bridge. A robot that joins later is served only from when it joins."""

from __future__ import annotations

import time

import anyio
import pytest
from simros1 import WHY_NOT, children, loopback

from btcap.actors import Clock
from btcap.bt.tree import Tree
from btcap.sim.ros1.client import RobotLink1
from btcap.sim.ros1.host import Ros1Host
from btcap.sim.running.hosts import registry
from tests.sim.rosbase.rosworld import world

pytestmark = [
    pytest.mark.ros1,
    pytest.mark.skipif(WHY_NOT is not None, reason=str(WHY_NOT)),
    pytest.mark.usefixtures("loopback"),
    pytest.mark.timeout(200),
]

__all__ = ["loopback"]


async def until(link: RobotLink1, missing: int) -> None:
    """Until ``missing`` of the link's servers are gone from its bridge's view."""

    def wait() -> bool:
        while len(link.missing()) != missing:
            anyio.from_thread.check_cancelled()
            time.sleep(0.02)
        return True

    assert await anyio.to_thread.run_sync(wait, abandon_on_cancel=True)


def links_of(host: Ros1Host) -> dict[str, RobotLink1]:
    """The started host's robot links by robot."""
    assert host.started is not None
    assert host.started.links is not None
    return host.started.links.links


async def test_a_failed_or_left_robot_withdraws_its_servers_until_it_is_back() -> None:
    s, grid, manager = world("full-team")
    with anyio.fail_after(150):
        async with Ros1Host(s, Clock(s.speedup), registry(), grid, manager=manager) as host:
            bebop, husky = links_of(host)["bebop1"], links_of(host)["husky1"]
            assert bebop.missing() == []
            assert husky.missing() == []
            servers = len(bebop.servers)  # move_base and its operations
            host.fail("bebop1")
            await until(bebop, servers)
            assert husky.missing() == []
            host.recover("bebop1")
            await until(bebop, 0)
            host.leave("husky1")
            await until(husky, len(husky.servers))
            host.start("husky1")  # joins again
            await until(husky, 0)
            assert bebop.missing() == []
    assert children() == []


async def test_a_late_joiner_is_served_only_from_when_it_joins() -> None:
    s, grid, manager = world("huskies-bebop-joins")  # bebop1 joins at 120 s
    with anyio.fail_after(150):
        async with Ros1Host(s, Clock(s.speedup), registry(), grid, manager=manager) as host:
            bebop, husky = links_of(host)["bebop1"], links_of(host)["husky1"]
            # Entered once the present robots' servers were found: the joiner's never were.
            assert len(bebop.missing()) == len(bebop.servers)
            assert husky.missing() == []
            host.start("bebop1")  # it joins
            await until(bebop, 0)
            host.leave("bebop1")
            await until(bebop, len(bebop.servers))
            assert husky.missing() == []
    assert children() == []


async def test_a_robot_withdrawn_mid_drive_stops_and_its_goal_ends() -> None:
    """husky1 drives to the farthest cell through its move_base (its own bridge's
    RosAction) when its servers are withdrawn: its execution gives up and the robot stops
    where it is, as behind ROS 2 (it drove on to the goal, and the execution ended later
    on a server gone from the graph)."""
    import numpy as np

    from btcap.actors import ActorSystem
    from btcap.bt.state import State
    from btcap.ros.nodes1 import RosAction
    from btcap.sim.running.hosts import SIM_SYSTEM
    from btcap.sim.world.manager import SimulationManager

    s, grid, manager = world("full-team")
    free = np.argwhere(grid.free)
    far = free[np.argmax(np.abs(free - np.array(grid.start)).sum(axis=1))]
    x, y = float(far[1]) * grid.cell_size_m, float(far[0]) * grid.cell_size_m
    target = {"header": {"frame_id": "map"}, "pose": {"position": {"x": x, "y": y}}}
    for r in s.robots:
        manager.add_robot(r.name, s.models()[r.model])
    clock, reg = Clock(5.0), registry()
    with anyio.fail_after(150):
        async with (
            Ros1Host(s, clock, reg, grid, manager=manager) as host,
            ActorSystem(
                SIM_SYSTEM, transport=host.transport(SIM_SYSTEM), registry=reg, clock=clock
            ) as sim,
        ):
            sim.spawn(manager, SimulationManager.PATH)
            assert host.started is not None
            assert host.started.servers is not None
            husky = links_of(host)["husky1"]
            nav = RosAction(
                "go",
                action_type="move_base_msgs/MoveBase",
                action_name="move_base",
                bridge=husky.bridge,
                inputs={"target_pose": target},
                server_timeout=30.0,
            )
            tree = Tree(nav)
            tree.setup()
            while nav.outputs["feedback_base_position"] is None:
                assert tree.tick() is State.RUNNING, nav.error
                await anyio.sleep(0.01)
            assert manager.robots["husky1"].move is not None
            host.started.servers.withdraw("husky1")
            while (state := tree.tick()) is State.RUNNING:  # noqa: ASYNC110 (ticking)
                await anyio.sleep(0.01)
            assert state is State.FAILED
            while manager.robots["husky1"].move is not None:  # noqa: ASYNC110 (the loop's)
                await anyio.sleep(0.01)
            assert manager.position("husky1") != tuple(far)  # stopped, not driven on
            assert "the goal was aborted" in str(nav.error), nav.error
            await tree.shutdown()
    assert children() == []
