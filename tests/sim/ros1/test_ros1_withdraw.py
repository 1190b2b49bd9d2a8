"""A robot that fails or leaves a scenario behind ROS 1 takes its servers out of the ROS
graph, as a real robot would, and gets them back when it recovers or joins again: the
host's ``fail``/``leave``/``recover``/``start`` (what a scenario's events call), seen by
the robot's own bridge. A robot that joins later is served only from when it joins."""

from __future__ import annotations

import contextlib
import time
from collections.abc import AsyncIterator
from typing import Any

import anyio
import numpy as np
import pytest
from simros1 import WHY_NOT, children, loopback

from btcap.actors import ActorSystem, Clock
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.nodes1 import RosAction
from btcap.sim.ros1.client import RobotLink1
from btcap.sim.ros1.host import Ros1Host
from btcap.sim.running.hosts import SIM_SYSTEM, registry
from btcap.sim.world.distance import Cell
from btcap.sim.world.manager import SimulationManager
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


@contextlib.asynccontextmanager
async def simulated() -> AsyncIterator[tuple[Ros1Host, SimulationManager, dict[str, Any], Cell]]:
    """The full team behind ROS 1, its simulation manager running, and a move_base target
    pose at the free cell farthest from the start (the cell too)."""
    s, grid, manager = world("full-team")
    free = np.argwhere(grid.free)
    far = free[np.argmax(np.abs(free - np.array(grid.start)).sum(axis=1))]
    x, y = float(far[1]) * grid.cell_size_m, float(far[0]) * grid.cell_size_m
    target = {"header": {"frame_id": "map"}, "pose": {"position": {"x": x, "y": y}}}
    for r in s.robots:
        manager.add_robot(r.name, s.models()[r.model])
    clock, reg = Clock(5.0), registry()
    async with (
        Ros1Host(s, clock, reg, grid, manager=manager) as host,
        ActorSystem(
            SIM_SYSTEM, transport=host.transport(SIM_SYSTEM), registry=reg, clock=clock
        ) as sim,
    ):
        sim.spawn(manager, SimulationManager.PATH)
        assert host.started is not None
        assert host.started.servers is not None
        yield host, manager, target, (int(far[0]), int(far[1]))


def go(host: Ros1Host, target: dict[str, Any], name: str = "go") -> tuple[Tree, RosAction]:
    """A tree of one RosAction sending husky1's move_base to ``target``, set up."""
    nav = RosAction(
        name,
        action_type="move_base_msgs/MoveBase",
        action_name="move_base",
        bridge=links_of(host)["husky1"].bridge,
        inputs={"target_pose": target},
        server_timeout=30.0,
    )
    tree = Tree(nav)
    tree.setup()
    return tree, nav


async def test_a_robot_withdrawn_mid_drive_stops_and_its_goal_ends() -> None:
    """husky1 drives to the farthest cell through its move_base (its own bridge's
    RosAction) when its servers are withdrawn: its execution gives up and the robot stops
    where it is, as behind ROS 2 (it drove on to the goal, and the execution ended later
    on a server gone from the graph)."""
    with anyio.fail_after(150):
        async with simulated() as (host, manager, target, far):
            assert host.started is not None
            assert host.started.servers is not None
            tree, nav = go(host, target)
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
            assert manager.position("husky1") != far  # stopped, not driven on
            assert "the goal was aborted" in str(nav.error), nav.error
            await tree.shutdown()
    assert children() == []


async def test_a_goal_taken_just_before_a_withdraw_ends_with_it_undriven() -> None:
    """A second goal preempts the first: actionlib's SimpleActionServer holds it PENDING
    until its loop takes it up, up to 0.1 s after the first one ended. Withdrawn at once
    after that end, the robot's close() waited only for executions running: it saw none,
    stopped the server, and the goal was taken up after, never answered. Now close() waits
    for it too: it ends ABORTED, without driving."""
    with anyio.fail_after(150):
        async with simulated() as (host, manager, target, far):
            assert host.started is not None
            assert host.started.servers is not None
            first, one = go(host, target, "first")
            while one.outputs["feedback_base_position"] is None:
                assert first.tick() is State.RUNNING, one.error
                await anyio.sleep(0.01)
            second, two = go(host, target, "second")
            while (state := first.tick()) is State.RUNNING:
                assert second.tick() is State.RUNNING, two.error
                await anyio.sleep(0.002)
            host.started.servers.withdraw("husky1")  # as soon as the first one ended
            assert "the goal was preempted" in str(one.error), one.error
            while (state := second.tick()) is State.RUNNING:  # noqa: ASYNC110 (ticking)
                await anyio.sleep(0.01)
            assert state is State.FAILED
            assert "the goal was aborted" in str(two.error), two.error
            while manager.robots["husky1"].move is not None:  # noqa: ASYNC110 (the loop's)
                await anyio.sleep(0.01)
            assert manager.position("husky1") != far
            await first.shutdown()
            await second.shutdown()
    assert children() == []
