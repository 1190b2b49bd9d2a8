"""The robots' side of the simulator behind ROS 2 closes its robots' bridges all at once
(each waits up to CLOSE_WAIT_S for its servers to answer its cancels: one by one, a team's
close took the sum), and the servers' side leaves no executor thread behind."""

from __future__ import annotations

import asyncio
import threading

import anyio
import numpy as np
import pytest
from simserving import serving

from btcap.actors import Clock
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.model import paper_team
from btcap.sim.world.store import MissionState

pytestmark = [pytest.mark.ros]


async def test_the_robots_bridges_close_at_once_and_the_servers_leave_no_thread(
    ros_domain: int,
) -> None:
    from btcap.ros.loader import load

    load()
    from btcap.sim.ros2.client import RobotLinks

    team = paper_team()
    robots = {"husky1": team["husky"], "spot1": team["spot"], "bebop1": team["bebop"]}
    s = load_scenario(builtin_scenarios()["full-team"])
    grid = s.grid()
    state = MissionState.scatter(grid, s.objects, s.contaminated_share, np.random.default_rng(1))
    manager = SimulationManager(state, SimConfig(failure_chance=0.0))
    for name, model in robots.items():
        manager.add_robot(name, model)
    closing: dict[str, threading.Thread] = {}
    with anyio.fail_after(90):
        async with serving(manager, robots, grid, Clock(5.0), domain_id=ros_domain) as servers:
            loop = asyncio.get_running_loop()
            ros = ScenarioRos(domain_id=ros_domain)
            links = await anyio.to_thread.run_sync(lambda: RobotLinks(loop, robots, ros))
            assert await anyio.to_thread.run_sync(links.wait_for_servers) == []
            # A drive under way as the links close: its execution runs on the servers' pool.
            from btcap_sim_msgs.action import NavigateToPose

            goal = NavigateToPose.Goal()
            goal.pose.pose.position.x, goal.pose.pose.position.y = 30.0, 30.0
            husky = links.links["husky1"]
            sent, _ = husky.bridge.send_goal(husky.clients[0], goal, None)
            while not sent.done():  # noqa: ASYNC110 (set by rclpy's thread)
                await anyio.sleep(0.01)
            assert sent.result().accepted
            for name, bridge in links.bridges.items():
                close = bridge.close

                def on_close(name: str = name, close: object = close) -> None:
                    closing[name] = threading.current_thread()
                    close()  # type: ignore[operator]

                bridge.close = on_close  # type: ignore[method-assign]
            caller = await anyio.to_thread.run_sync(
                lambda: (links.close(), threading.current_thread())[1]
            )
    assert set(closing) == set(robots)
    assert len({id(t) for t in closing.values()}) == len(robots), closing  # held: ids unique
    assert all(t is not caller for t in closing.values())
    assert all(b.node is None for b in links.bridges.values())
    # rclpy's shutdown() neither waits for its executor's callbacks nor ends its threads
    pool = servers.executor._executor
    assert pool._threads
    assert not [t for t in pool._threads if t.is_alive()]
    assert servers.robots["husky1"].running == 0
