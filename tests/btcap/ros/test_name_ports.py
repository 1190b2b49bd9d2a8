"""action_name, service_name and topic_name are input ports, as in BehaviorTree.ROS2: a
literal or a blackboard entry (``action_name="{which}"``), resolved in the robot's
namespace and read when a goal, call or wait starts."""

from __future__ import annotations

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, tick_until, wait_for

from btcap.bt.files import loads_tree
from btcap.bt.registry import default_registry
from btcap.bt.state import State, TreeError
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.agent import register
from btcap.ros.base import give
from btcap.ros.capability import Server, servers_of
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError

pytestmark = pytest.mark.ros

FIB = "test_msgs/action/Fibonacci"

XML = f"""<root BTCPP_format="4">
  <BehaviorTree ID="main">
    <Sequence>
      <RosAction name="fib" action_type="{FIB}" action_name="{{which}}"
                 server_timeout="{FOUND_S}" order="5" sequence="{{sequence}}"/>
      <RosService name="call" service_type="std_srvs/srv/SetBool"
                  service_name="{{srv}}" server_timeout="{FOUND_S}" data="true"/>
      <RosWaitForMessage name="pose" topic_type="geometry_msgs/msg/PoseStamped"
                         topic_name="{{pose_topic}}"/>
    </Sequence>
  </BehaviorTree>
</root>"""


def xml_tree(bridge: RosBridge, **entries: str) -> Tree:
    tree = loads_tree(XML, "xml", register(default_registry()), entries=entries)
    assert give(bridge, tree) == 3
    return tree


async def test_names_from_the_blackboard_resolve_in_the_robot_namespace(
    ros_domain: int, bridge: RosBridge
) -> None:
    with Servers("/husky1", domain_id=ros_domain, pose=(1.0, 2.0)) as servers:
        tree = xml_tree(bridge, which="fibonacci", srv="set_bool", pose_topic="pose")
        fib = tree.find("Sequence/fib")
        assert isinstance(fib, RosAction)
        assert servers_of(tree) == []  # known only when the nodes run
        with anyio.fail_after(20):
            state = await tick_until(tree)
        assert state is State.SUCCEEDED, [n.error for n in tree.nodes() if n.error]
        assert fib.action_name == "/husky1/fibonacci"
        assert servers.events["fibonacci.succeeded"] == 1
        assert servers.events["set_bool"] == 1
        # Another name for the next goal: it goes there.
        assert tree.blackboard is not None
        tree.blackboard["which"] = "fibonacci_abort"
        tree.reset()
        with anyio.fail_after(20):
            state = await tick_until(tree)
        assert state is State.FAILED
        assert (
            "action /husky1/fibonacci_abort (test_msgs/action/Fibonacci): the goal was "
            "aborted" in str(fib.error)
        )
        await tree.shutdown()


async def test_a_name_changed_while_a_goal_runs_takes_effect_at_the_next_goal(
    servers: Servers, bridge: RosBridge
) -> None:
    tree = xml_tree(bridge, which="fibonacci_hold", srv="set_bool", pose_topic="pose")
    fib = tree.find("Sequence/fib")
    assert tree.blackboard is not None
    with anyio.fail_after(20):
        await tick_until(tree, lambda _s: servers.events["fibonacci_hold.accepted"] == 1)
        tree.blackboard["which"] = "fibonacci"
        for _ in range(5):
            assert tree.tick() is State.RUNNING
            await anyio.sleep(0.01)
        assert fib.action_name == "/husky1/fibonacci_hold"  # the goal runs where it went
        assert servers.events["fibonacci.accepted"] == 0
        tree.untick()  # halted: cancelled on the old server
        await wait_for(lambda: servers.events["fibonacci_hold.canceled"] == 1)
        await tick_until(tree, lambda _s: servers.events["fibonacci.succeeded"] == 1)
    assert servers.events["fibonacci_hold.accepted"] == 1
    await tree.shutdown()


async def test_a_bad_or_missing_name_is_one_line_naming_the_node_and_port(
    bridge: RosBridge,
) -> None:
    tree = xml_tree(bridge, which="", srv="set_bool", pose_topic="pose")
    with anyio.fail_after(10):
        await tick_until(tree)
    fib = tree.find("Sequence/fib")
    assert fib.state is State.ERROR
    line = str(fib.error)
    assert isinstance(fib.error, RosError)
    assert "\n" not in line
    assert "RosAction 'Sequence/fib' input 'action_name': expected a non-empty" in line
    await tree.shutdown()
    with pytest.raises(TreeError, match=r"\{which\} \(str, read by .*fib\.action_name\)"):
        xml_tree(bridge, srv="set_bool", pose_topic="pose").setup()
    with pytest.raises(TreeError, match="'action_name': expected str, got int 5"):
        RosAction("fib", action_type=FIB, action_name=5)  # type: ignore[arg-type]


def test_literal_names_are_the_servers_an_implementation_needs() -> None:
    node = RosAction("fib", action_type=FIB, action_name="fibonacci")
    assert servers_of(node) == [Server("action", FIB, "fibonacci")]
    assert node.inputs["action_name"] == "fibonacci"
    assert node.literal_name() == "fibonacci"
