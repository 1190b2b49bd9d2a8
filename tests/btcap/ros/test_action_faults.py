"""RosAction when things go wrong: the server dies mid-goal, feedback floods at 1 kHz,
the goal or the type is wrong, the bridge closes with a goal open."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import weakref
from collections.abc import Iterator
from pathlib import Path

import anyio
import pytest
from rostools import FOUND_S, tick_until, tree_of, wait_for

from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"
HERE = Path(__file__).parent


@pytest.fixture
def server_process(ros_domain: int) -> Iterator[subprocess.Popen[str]]:
    """rosservers.py in a process of its own, namespace /husky1."""
    with subprocess.Popen(
        [sys.executable, str(HERE / "rosservers.py"), "/husky1"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(HERE)},
    ) as proc:
        try:
            assert proc.stdout is not None
            assert proc.stdout.readline().strip() == "ready"
            yield proc
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=10)


async def test_a_server_killed_mid_goal_fails_the_node_saying_why(
    server_process: subprocess.Popen[str], bridge: RosBridge
) -> None:
    node = RosAction(
        "act",
        action_type=FIB,
        action_name="fibonacci_hold",
        feedback_timeout=1.0,
        server_timeout=5.0,
        bridge=bridge,
        inputs={"order": 1},
    )
    with anyio.fail_after(20):
        tree = tree_of(node)
        outputs = node.outputs
        await tick_until(tree, lambda s: outputs["feedback_sequence"] is not None)
        server_process.send_signal(signal.SIGKILL)
        state = await tick_until(tree)
    assert state is State.FAILED
    why = str(node.error)
    assert "no feedback for feedback_timeout 1.0 s" in why or "the server left" in why, why
    assert bridge.open_goals() == 0
    # The goal never ends for rclpy's client, which keeps its callbacks: they must not
    # hold the node's tree.
    gone = weakref.ref(tree)
    del node, tree
    gc.collect()
    assert gone() is None


async def test_a_1khz_feedback_stream_does_not_stall_ticking(
    servers: object, bridge: RosBridge
) -> None:
    """300 feedback messages at ~1 kHz: the tick keeps going (the callbacks only store),
    and sees the feedback change many times, not once at the end."""
    node = RosAction(
        "act",
        action_type=FIB,
        action_name="fibonacci_stream",
        bridge=bridge,
        inputs={"order": 300},
        server_timeout=FOUND_S,
    )
    ticks = 0
    changes: set[int] = set()

    def count(state: State) -> bool:
        nonlocal ticks
        ticks += 1
        fb = node.outputs["feedback_sequence"]
        if fb is not None:
            changes.add(fb[-1])
        return state is not State.RUNNING

    with anyio.fail_after(20):
        state = await tick_until(tree_of(node), count)
    assert state is State.SUCCEEDED, node.error
    assert len(node.outputs["sequence"]) == 302
    assert len(changes) >= 10, (ticks, len(changes))


async def test_wrong_goal_fields_fail_with_one_line_naming_the_field(
    servers: object, bridge: RosBridge
) -> None:
    node = RosAction(
        "act",
        action_type=FIB,
        action_name="fibonacci",
        bridge=bridge,
        inputs={"order": 5},
        server_timeout=FOUND_S,
    )
    node.inputs["order"] = "five"  # as a wire from a wrongly typed output would
    with anyio.fail_after(10):
        state = await tick_until(tree_of(node))
    assert state is State.ERROR
    line = str(node.error)
    assert "\n" not in line
    assert "goal.order: 'five' does not fit int32" in line
    with pytest.raises(
        Exception, match=r"node 'act' .*has no input 'ordr'; inputs: action_name, order"
    ):
        RosAction("act", action_type=FIB, action_name="fibonacci", inputs={"ordr": 5})


@pytest.mark.parametrize(
    ("type_name", "why"),
    [
        ("test_msgs/action/Fibonaci", "test_msgs has no action 'Fibonaci'; it has "),
        ("no_such_msgs/action/Go", "no package 'no_such_msgs' with action interfaces"),
        ("test_msgs/msg/Fibonacci", "expected an action, not a msg"),
        ("Fibonacci", "expected 'package/action/Name'"),
    ],
)
def test_an_unknown_interface_type_is_one_line(type_name: str, why: str) -> None:
    with pytest.raises(RosError) as err:
        RosAction("act", action_type=type_name, action_name="x")
    assert why in str(err.value)
    assert "\n" not in str(err.value)


async def test_closing_the_bridge_cancels_open_goals_and_leaves_no_thread(
    servers: object, ros_domain: int
) -> None:
    import threading

    before = set(threading.enumerate())
    bridge = await RosBridge(RosSettings(domain_id=ros_domain), robot="husky1").__aenter__()
    node = RosAction(
        "act",
        action_type=FIB,
        action_name="fibonacci_hold",
        bridge=bridge,
        inputs={"order": 1},
        server_timeout=FOUND_S,
    )
    with anyio.fail_after(10):
        tree: Tree = tree_of(node)
        await tick_until(tree, lambda s: bridge.open_goals() == 1)
        await bridge.__aexit__(None, None, None)
        await wait_for(lambda: servers.events["fibonacci_hold.canceled"] == 1)  # type: ignore[attr-defined]
    left = [t.name for t in set(threading.enumerate()) - before if t.name.startswith("btcap-ros")]
    assert not left, left
    assert bridge.node is None


async def test_a_service_killed_mid_call_fails_the_node_saying_why(
    server_process: subprocess.Popen[str], bridge: RosBridge
) -> None:
    """As a RosAction whose server leaves mid-goal: the call fails once the server is
    gone from the graph, not only when server_timeout (here a minute) is up."""
    from btcap.ros.service import RosService

    node = RosService(
        "call",
        service_type="std_srvs/srv/SetBool",
        service_name="set_bool_slow",
        server_timeout=60.0,
        bridge=bridge,
        inputs={"data": True},
    )
    with anyio.fail_after(45):
        tree = tree_of(node)
        await tick_until(tree, lambda s: node._future is not None)
        server_process.send_signal(signal.SIGKILL)
        state = await tick_until(tree)
    assert state is State.FAILED
    assert str(node.error).endswith("(std_srvs/srv/SetBool): the server left during the call")
