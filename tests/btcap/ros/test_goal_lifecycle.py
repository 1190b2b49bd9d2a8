"""A RosAction's goals over a robot's life: rejected, halted before and after the server
accepted them, preempted by the next goal of the same node, and open when the bridge
closes. Each ends on the server, and nothing of it stays in the client (rclpy keeps a
feedback callback per goal, which holds the node and its tree, until it sees the result)."""

from __future__ import annotations

from typing import Any

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, tick_until, tree_of, wait_for

from btcap.bt.state import State
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"
#: What rclpy's ActionClient keeps per goal until the goal is over for it.
_PER_GOAL = (
    "_feedback_callbacks",
    "_pending_goal_requests",
    "_goal_sequence_number_to_goal_id",
    "_pending_cancel_requests",
    "_pending_result_requests",
    "_result_sequence_number_to_goal_id",
)


def _kept(bridge: RosBridge) -> dict[str, int]:
    kept: dict[str, int] = {}
    for client in bridge._clients.values():
        for attr in _PER_GOAL:
            if getattr(client, attr, None):
                kept[attr] = kept.get(attr, 0) + len(getattr(client, attr))
    return kept


async def _settled(bridge: RosBridge) -> dict[str, int]:
    """What the clients keep once the answers in flight came (at most 5 s)."""
    with anyio.move_on_after(5):
        await wait_for(lambda: not _kept(bridge) and not bridge._goals)
    return _kept(bridge)


def action(bridge: RosBridge, name: str, order: int = 3) -> RosAction:
    return RosAction(
        "act",
        action_type=FIB,
        action_name=name,
        bridge=bridge,
        inputs={"order": order},
        server_timeout=FOUND_S,
    )


async def test_rejected_goals_leave_nothing_in_the_client(
    servers: Servers, bridge: RosBridge
) -> None:
    node = action(bridge, "fibonacci_reject")
    tree = tree_of(node)
    with anyio.fail_after(20):
        for _ in range(5):
            assert await tick_until(tree) is State.FAILED
            assert "rejected" in str(node.error)
        assert await _settled(bridge) == {}
    assert servers.events["fibonacci_reject.rejected"] == 5
    await tree.shutdown()


async def test_tick_halt_cycles_cancel_every_goal_and_the_last_result_is_its_own(
    servers: Servers, bridge: RosBridge
) -> None:
    """Halted before acceptance (fibonacci_late), after (fibonacci_hold), re-ticked at
    once: every goal is cancelled on the server, the client keeps nothing, and a goal
    after them succeeds with its own result, not a cancelled one's."""
    with anyio.fail_after(30):
        late = action(bridge, "fibonacci_late")
        tree = tree_of(late)
        for _ in range(3):
            assert tree.tick() is State.RUNNING
            tree.untick()  # before the server accepts it (LATE_S later)
        hold = action(bridge, "fibonacci_hold")
        tree2 = tree_of(hold)
        for i in range(3):
            await tick_until(tree2, lambda s, i=i: servers.events["fibonacci_hold.accepted"] > i)
            await wait_for(lambda: hold._goal is not None and hold._goal.handle is not None)
            tree2.untick()
        await wait_for(lambda: servers.events["fibonacci_late.canceled"] == 3)
        await wait_for(lambda: servers.events["fibonacci_hold.canceled"] == 3)
        fib = action(bridge, "fibonacci", order=4)
        tree3 = tree_of(fib)
        assert await tick_until(tree3) is State.SUCCEEDED, fib.error
        assert fib.outputs["sequence"] == [0, 1, 1, 2, 3, 5]
        assert await _settled(bridge) == {}
    assert servers.events["fibonacci_late.accepted"] == 3
    assert servers.events["cancel_requests"] == 6
    assert bridge.open_goals() == 0
    for t in (tree, tree2, tree3):
        await t.shutdown()


async def test_closing_the_bridge_cancels_a_goal_the_server_had_not_accepted_yet(
    servers: Servers, ros_domain: int
) -> None:
    """Closed right after sending: the server accepts LATE_S later, and would then run
    the goal with nobody to stop it."""
    bridge = await RosBridge(RosSettings(domain_id=ros_domain), robot="husky1").__aenter__()
    node: Any = action(bridge, "fibonacci_late")
    with anyio.fail_after(15):
        tree = tree_of(node)
        await tick_until(tree, lambda s: node._goal is not None)
        await bridge.__aexit__(None, None, None)
        assert servers.events["fibonacci_late.accepted"] == 1  # close waited for the answer
        await wait_for(lambda: servers.events["fibonacci_late.canceled"] == 1)
    assert bridge.node is None
