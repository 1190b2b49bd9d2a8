"""A robot that fails or leaves a scenario behind ROS 2 takes its action servers out of the
ROS graph, as a real robot would, and gets them back when it recovers or joins again: the
host's ``fail``/``leave``/``recover``/``start`` (what a scenario's events call), seen by
the robot's own bridge. A robot that joins later is served only from when it joins."""

from __future__ import annotations

import time

import anyio
import pytest

from btcap.actors import Clock
from btcap.sim.running.hosts import registry
from tests.sim.rosbase.rosworld import world

pytestmark = [pytest.mark.ros, pytest.mark.timeout(200)]


async def until(link: object, missing: int) -> None:
    """Until ``missing`` of the link's action servers are gone from its bridge's view."""
    clients = link.clients  # type: ignore[attr-defined]

    def wait() -> bool:
        while sum(not c.server_is_ready() for c in clients) != missing:
            anyio.from_thread.check_cancelled()
            time.sleep(0.02)
        return True

    assert await anyio.to_thread.run_sync(wait, abandon_on_cancel=True)


async def test_a_failed_or_left_robot_withdraws_its_servers_until_it_is_back(
    ros_domain: int,
) -> None:
    from btcap.sim.ros2.host import Ros2Host

    s, grid, manager = world("full-team")
    with anyio.fail_after(150):
        async with Ros2Host(s, Clock(s.speedup), registry(), grid, manager=manager) as host:
            assert host.links is not None
            bebop, husky = host.links.links["bebop1"], host.links.links["husky1"]
            await until(bebop, 0)
            await until(husky, 0)
            host.fail("bebop1")
            await until(bebop, len(bebop.clients))
            await until(husky, 0)
            host.recover("bebop1")
            await until(bebop, 0)
            host.leave("husky1")
            await until(husky, len(husky.clients))
            host.start("husky1")  # joins again
            await until(husky, 0)
            assert sorted(host.servers.served()) == sorted(r.name for r in s.robots)  # type: ignore[union-attr]


async def test_a_late_joiner_is_served_only_from_when_it_joins(ros_domain: int) -> None:
    from btcap.sim.ros2.host import Ros2Host

    s, grid, manager = world("huskies-bebop-joins")  # bebop1 joins at 120 s
    with anyio.fail_after(150):
        async with Ros2Host(s, Clock(s.speedup), registry(), grid, manager=manager) as host:
            assert host.links is not None
            assert host.servers is not None
            bebop, husky = host.links.links["bebop1"], host.links.links["husky1"]
            # Entered once the present robots' servers were found: the joiner's never were.
            assert [c.server_is_ready() for c in bebop.clients] == [False] * len(bebop.clients)
            assert sorted(host.servers.served()) == ["husky1", "husky2"]
            await until(husky, 0)
            host.start("bebop1")  # it joins
            await until(bebop, 0)
            host.leave("bebop1")
            await until(bebop, len(bebop.clients))
