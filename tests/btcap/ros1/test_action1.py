"""RosAction over ROS 1: real actionlib servers (servers1.py) on a real master of the
test's own, each way a goal can end, said in the node's error."""

from __future__ import annotations

import gc
import weakref

import anyio
import pytest
from conftest import Servers
from rosmaster1 import Master
from tools1 import FOUND_S, bridge_on, registered, run, settle

from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.client1 import Ros1Bridge
from btcap.ros.errors import RosError
from btcap.ros.nodes1 import RosAction

pytestmark = pytest.mark.ros1

TEST = "actionlib/Test"


def count_node(bridge: Ros1Bridge, goal: int, name: str = "count", **options: object) -> RosAction:
    options.setdefault("server_timeout", FOUND_S)
    return RosAction(
        "act", action_type=TEST, action_name=name, bridge=bridge, inputs={"goal": goal}, **options
    )


async def test_a_goal_succeeds_with_feedback_then_the_result(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, 5)
            seen: list[int] = []

            def watch(state: State) -> bool:
                fb = node.outputs["feedback_feedback"]
                if fb is not None and (not seen or seen[-1] != fb):
                    seen.append(fb)
                return state is not State.RUNNING

            assert await run(node, watch) is State.SUCCEEDED, node.error
            assert node.outputs["result"] == 10
            assert seen
            assert seen[-1] == 4
            assert seen == sorted(seen)
    assert servers.events["count.succeeded"] == 1


async def test_move_base_goal_from_inputs_feedback_to_outputs(
    master: Master, servers: Servers
) -> None:
    target = {"header": {"frame_id": "map"}, "pose": {"position": {"x": 2.0, "y": 3.0}}}
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosAction(
                "nav",
                action_type="move_base_msgs/MoveBase",
                action_name="move_base",
                bridge=bridge,
                inputs={"target_pose": target},
                server_timeout=FOUND_S,
            )
            assert await run(node) is State.SUCCEEDED, node.error
            fb = node.outputs["feedback_base_position"]
            assert fb["header"]["frame_id"] == "map"
            assert fb["pose"]["position"] == {"x": 2.0, "y": 3.0, "z": 0.0}
    assert servers.events["move_base.succeeded"] == 1


@pytest.mark.parametrize(
    ("name", "goal", "why"),
    [("count", -1, "the goal was aborted"), ("picky", 1, "the goal was rejected by the server")],
)
async def test_abort_and_reject_fail_naming_the_status(
    master: Master, servers: Servers, name: str, goal: int, why: str
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, goal, name)
            assert await run(node) is State.FAILED
    assert isinstance(node.error, RosError)
    assert str(node.error) == f"RosAction 'act': action /husky1/{name} ({TEST}): {why}"


async def test_a_missing_server_fails_within_server_timeout_saying_so(master: Master) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, 1, "nobody", wait_for_server_timeout=0.3)
            assert await run(node) is State.FAILED
    assert str(node.error).endswith(
        f"action /husky1/nobody ({TEST}): no server within wait_for_server_timeout 0.3 s"
    )


async def test_halt_after_acceptance_preempts_the_goal(master: Master, servers: Servers) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, -2)
            await run(node, lambda s: node.outputs["feedback_feedback"] is not None)
            node._tree.untick()  # type: ignore[union-attr]
            node._tree.untick()  # type: ignore[union-attr]  # twice: nothing more
            await settle(lambda: servers.events["count.preempted"] == 1)
            assert bridge.open_goals() == 0
    assert servers.events["count.preempted"] == 1
    assert servers.events["count.succeeded"] == 0


async def test_halt_before_acceptance_cancels_the_goal_at_once(
    master: Master, servers: Servers
) -> None:
    """actionlib takes a cancel of a goal it has not accepted (it recalls it, even one
    whose cancel comes first), so the halt sends it at once; the bridge keeps nothing
    of the goal after."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, 1, "slow")
            await run(node, lambda s: servers.events["slow.goal"] == 1)
            node._tree.untick()  # type: ignore[union-attr]
            assert bridge._handles == {}
            await settle(lambda: servers.events["slow.recalled"] + servers.events["slow.canceled"])
    assert servers.events["slow.succeeded"] == 0


async def test_a_goal_whose_server_died_holds_nothing_of_the_tree(
    master: Master, servers: Servers
) -> None:
    """A goal of a killed server never ends for actionlib: once the node gave it up, the
    bridge keeps nothing of it (its callbacks hold the node and its tree)."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, -4)
            tree = Tree(node)
            tree.setup()
            outputs = node.outputs
            await run(node, lambda s: outputs["feedback_feedback"] is not None)
            servers.kill()
            assert await run(node) is State.FAILED
            assert bridge._handles == {}
            gone = weakref.ref(tree)
            del node, tree
            gc.collect()
            assert gone() is None


async def test_a_server_killed_mid_goal_fails_the_node_saying_why(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, -4)
            await run(node, lambda s: node.outputs["feedback_feedback"] is not None)
            servers.kill()
            assert await run(node) is State.FAILED
    assert str(node.error).endswith(f"({TEST}): the server left during the goal")


async def test_no_feedback_within_feedback_timeout_fails_and_preempts(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, -5, feedback_timeout=0.5)
            assert await run(node) is State.FAILED
    assert str(node.error).endswith("no feedback for feedback_timeout 0.5 s")


@pytest.mark.parametrize(
    ("goal", "name", "ended"), [(-2, "count", "count.preempted"), (1, "slow", "")]
)
async def test_no_result_within_result_timeout_cancels_the_goal_and_fails(
    master: Master, servers: Servers, goal: int, name: str, ended: str
) -> None:
    """``count`` -2 runs (feedback and all) until canceled; ``slow`` accepts only 0.5 s
    after the goal came: past result_timeout either is canceled (recalled if not
    accepted yet) and the node fails saying so. Without it both ran on (RUNNING)."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, goal, name, result_timeout=0.3)
            assert await run(node) is State.FAILED
            if ended:
                await settle(lambda: servers.events[ended] == 1)
            else:
                await settle(
                    lambda: servers.events["slow.recalled"] + servers.events["slow.canceled"]
                )
            assert bridge.open_goals() == 0
    assert str(node.error).endswith(
        f"action /husky1/{name} ({TEST}): no result within result_timeout 0.3 s; the goal "
        "was cancelled"
    )
    assert servers.events["count.succeeded"] + servers.events["slow.succeeded"] == 0


async def test_a_feedback_flood_does_not_stall_ticking(master: Master, servers: Servers) -> None:
    """The server sends feedback as fast as it can for 1 s (thousands): the tick keeps
    going and sees it change many times; the rospy process sends only the latest while the
    pipe is busy, so the bridge reads at most what was sent."""
    ticks = 0
    changes: set[int] = set()
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, -3)

            def watch(state: State) -> bool:
                nonlocal ticks
                ticks += 1
                fb = node.outputs["feedback_feedback"]
                if fb is not None:
                    changes.add(fb)
                return state is not State.RUNNING

            assert await run(node, watch) is State.SUCCEEDED, node.error
    sent = node.outputs["result"]
    assert sent > 1000
    assert len(changes) >= 10, (ticks, len(changes), sent)


async def test_wrong_goal_fields_fail_with_one_line_naming_the_field(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = count_node(bridge, 1)
            node.inputs["goal"] = "five"
            assert await run(node) is State.ERROR
    line = str(node.error)
    assert "\n" not in line
    assert "goal.goal: 'five' does not fit int32" in line
    assert servers.events["count.goal"] == 0
    assert not [r for r in registered(master) if "/husky1/btcap" in r]  # nothing left
    with pytest.raises(
        Exception, match=r"node 'act' .*has no input 'gaol'; inputs: action_name, goal"
    ):
        RosAction("act", action_type=TEST, action_name="count", inputs={"gaol": 5})


@pytest.mark.parametrize(
    ("type_name", "why"),
    [
        ("actionlib/Tset", "actionlib has no action 'Tset'; it has Test, TestRequest, TwoInts"),
        ("no_such_msgs/Go", "no package 'no_such_msgs' with msg types is installed"),
        ("std_msgs/msg/String", "expected an action, not a msg"),
        ("Test", "expected 'package/Name'"),
    ],
)
def test_an_unknown_interface_type_is_one_line(type_name: str, why: str) -> None:
    with pytest.raises(RosError) as err:
        RosAction("act", action_type=type_name, action_name="x")
    assert why in str(err.value)
    assert "\n" not in str(err.value)
