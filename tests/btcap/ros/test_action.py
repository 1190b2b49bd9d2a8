"""RosAction against real ROS 2 action servers (tests/btcap/ros/rosservers.py)."""

from __future__ import annotations

import time
from typing import Any

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, tick_until, tree_of, wait_for

from btcap.bt.state import State
from btcap.ros.action import RosAction
from btcap.ros.base import SERVER_S, WAIT_FOR_SERVER_S
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"


def action(bridge: RosBridge, name: str, **kw: Any) -> RosAction:
    inputs = kw.pop("inputs", {"order": 5})
    kw.setdefault("server_timeout", FOUND_S)  # the server is there, unless a test says
    return RosAction("act", action_type=FIB, action_name=name, bridge=bridge, inputs=inputs, **kw)


async def test_a_goal_succeeds_with_feedback_then_the_result(
    servers: Servers, bridge: RosBridge
) -> None:
    node = action(bridge, "fibonacci", inputs={"order": 6})
    seen: list[Any] = []
    with anyio.fail_after(10):
        tree = tree_of(node)

        def running_with_feedback(s: State) -> bool:
            if node.outputs["feedback_sequence"] is not None:
                seen.append(node.outputs["feedback_sequence"])
            return s is not State.RUNNING

        state = await tick_until(tree, running_with_feedback)
    assert state is State.SUCCEEDED, node.error
    assert node.outputs["sequence"] == [0, 1, 1, 2, 3, 5, 8, 13]
    assert seen
    assert all(len(s) == 3 for s in seen)
    assert node.action_name == "/husky1/fibonacci"
    await tree.shutdown()


@pytest.mark.parametrize(
    ("name", "why"),
    [("fibonacci_abort", "the goal was aborted"), ("fibonacci_reject", "rejected by the server")],
)
async def test_abort_and_reject_fail_naming_the_status(
    servers: Servers, bridge: RosBridge, name: str, why: str
) -> None:
    node = action(bridge, name)
    with anyio.fail_after(10):
        state = await tick_until(tree_of(node))
    assert state is State.FAILED
    assert isinstance(node.error, RosError)
    assert why in str(node.error)
    assert f"/husky1/{name}" in str(node.error)


async def test_a_missing_server_fails_within_wait_for_server_timeout_saying_so(
    bridge: RosBridge,
) -> None:
    node = action(bridge, "nobody_here", wait_for_server_timeout=0.2)
    with anyio.fail_after(10):
        state = await tick_until(tree_of(node))
    assert state is State.FAILED
    assert "no server within wait_for_server_timeout 0.2 s" in str(node.error)
    assert "/husky1/nobody_here" in str(node.error)


async def test_halt_after_acceptance_cancels_the_goal_and_twice_is_harmless(
    servers: Servers, bridge: RosBridge
) -> None:
    node = action(bridge, "fibonacci_hold")
    with anyio.fail_after(10):
        tree = tree_of(node)
        await tick_until(tree, lambda s: servers.events["fibonacci_hold.accepted"] == 1)
        await wait_for(lambda: node._goal is not None and node._goal.handle is not None)
        tree.untick()
        tree.untick()
        await wait_for(lambda: servers.events["fibonacci_hold.canceled"] == 1)
    assert servers.events["cancel_requests"] == 1
    assert node.state is State.PAUSED


async def test_halt_before_acceptance_cancels_the_goal_once_accepted(
    servers: Servers, bridge: RosBridge
) -> None:
    node = action(bridge, "fibonacci_late", server_timeout=5.0)
    with anyio.fail_after(10):
        tree = tree_of(node)
        assert tree.tick() is State.RUNNING  # sent: the server accepts LATE_S later
        await wait_for(lambda: node._goal is not None)
        tree.untick()  # halted while the server has not accepted it yet
        await wait_for(lambda: servers.events["fibonacci_late.canceled"] == 1)
    assert servers.events["fibonacci_late.accepted"] == 1
    assert servers.events["cancel_requests"] == 1


@pytest.mark.parametrize("name", ["fibonacci_hold", "fibonacci_late"])
async def test_no_result_within_result_timeout_cancels_the_goal_and_fails(
    servers: Servers, bridge: RosBridge, name: str
) -> None:
    """``fibonacci_hold`` accepts and runs until canceled, ``fibonacci_late`` accepts only
    LATE_S after the goal came: past result_timeout either is canceled (the late one as
    soon as it is accepted) and the node fails saying so. Without it both ran on."""
    node = action(bridge, name, result_timeout=0.1)
    with anyio.fail_after(10):
        assert await tick_until(tree_of(node)) is State.FAILED
        await wait_for(lambda: servers.events[f"{name}.canceled"] == 1)
    assert str(node.error).endswith(
        f"action /husky1/{name} ({FIB}): no result within result_timeout 0.1 s; the goal "
        "was cancelled"
    )
    assert servers.events["cancel_requests"] == 1
    assert servers.events[f"{name}.succeeded"] == 0


def test_result_timeout_is_off_unless_set() -> None:
    assert RosAction.OPTIONS["result_timeout"].default is None


async def test_discovery_is_bounded_by_its_own_timeout_not_by_the_answer_one(
    bridge: RosBridge,
) -> None:
    """A server still being discovered after ``server_timeout`` is waited for (up to
    ``wait_for_server_timeout``, 10 s by default): on a loaded machine discovery takes
    seconds, while ``server_timeout`` bounds the answer of a server already found."""
    node = action(bridge, "not_yet", server_timeout=0.1)
    assert node.options["wait_for_server_timeout"] == WAIT_FOR_SERVER_S == 10.0
    assert RosAction.OPTIONS["server_timeout"].default == SERVER_S == 5.0
    with anyio.fail_after(10):
        tree = tree_of(node)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 0.5:  # five times server_timeout, no server
            assert tree.tick() is State.RUNNING, node.error
            await anyio.sleep(0.01)
    tree.untick()
    await tree.shutdown()
