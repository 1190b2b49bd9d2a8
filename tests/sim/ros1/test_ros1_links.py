"""The robots' side of the simulator behind ROS 1 closes its robots' bridges all at once:
each waits for its rospy process to cancel its goals, leave the master and exit, so one by
one a team's close took the sum of theirs."""

from __future__ import annotations

import asyncio
import threading
from pathlib import Path

import anyio
import pytest
from simros1 import WHY_NOT, children, loopback

from btcap.sim.ros1.client import RobotLinks1
from btcap.sim.ros1.master import RunMaster
from btcap.sim.world.model import paper_team
from btcap.team.rossettings import RosSettings

pytestmark = [
    pytest.mark.ros1,
    pytest.mark.skipif(WHY_NOT is not None, reason=str(WHY_NOT)),
    pytest.mark.usefixtures("loopback"),
    pytest.mark.timeout(120),
]

__all__ = ["loopback"]


async def test_the_robots_bridges_close_at_once_each_on_a_thread(tmp_path: Path) -> None:
    team = paper_team()
    robots = {"husky1": team["husky"], "spot1": team["spot"], "bebop1": team["bebop"]}
    master = await anyio.to_thread.run_sync(RunMaster(str(tmp_path)).start)
    try:
        with anyio.fail_after(90):
            settings = {name: RosSettings(backend="ros1", master_uri=master.uri) for name in robots}
            loop = asyncio.get_running_loop()
            links = await anyio.to_thread.run_sync(lambda: RobotLinks1(loop, robots, settings))
            closing: dict[str, threading.Thread] = {}
            for name, bridge in links.bridges.items():
                close = bridge.close

                def on_close(name: str = name, close: object = close) -> None:
                    closing[name] = threading.current_thread()
                    close()  # type: ignore[operator]

                bridge.close = on_close  # type: ignore[method-assign]
            caller = await anyio.to_thread.run_sync(
                lambda: (links.close(), threading.current_thread())[1]
            )
    finally:
        await anyio.to_thread.run_sync(master.stop)
    assert set(closing) == set(robots)
    assert len({id(t) for t in closing.values()}) == len(robots), closing  # held: ids unique
    assert all(t is not caller for t in closing.values())
    assert all(
        b.process is not None and b.process.returncode is not None for b in links.bridges.values()
    )
    assert not [c for c in children() if "btcap.ros.child1" in c]
