"""ROS 1: a robot whose only server for a ROS capability implementation has another type
declines to bid and says so once, naming the robot, the implementation and its capability,
the name and both types; a cost reading a topic published only with another type (a
distance bid's pose) says so once too (servers1.py serves ``count`` as actionlib/Test,
``set_flag`` as std_srvs/SetBool, publishes ``chatter_out`` as std_msgs/String). Before,
the bid was just None (a service of another type even counted as there, so the robot bid
and its node failed after the award) and ``latest()`` just stayed None, unsaid."""

from __future__ import annotations

from collections.abc import Callable

import anyio
import pytest
from conftest import Servers
from rosmaster1 import Master
from tools1 import bridge_on

from btcap.bt.composites import Sequence
from btcap.bt.node import Node
from btcap.bt.tree import Tree
from btcap.ros.capability import ros_implementation
from btcap.ros.client1 import Ros1Bridge
from btcap.ros.nodes1 import RosAction, RosService
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation

pytestmark = pytest.mark.ros1

COMPUTE = CapabilityInterface(
    "Compute", inputs={"order": int}, outputs={}, description="what the robot's server does"
)
INPUTS = {"order": 3}
DECLINED = "it declines to bid until a server of its type answers"
#: Questions asked after the lines came (a call for bids each, 20 ms apart: the rospy
#: process checks the types every 0.2 s): none may say it again.
AGAIN = 50


def implementation(name: str, node: Callable[[], Node], bridge: Ros1Bridge) -> Implementation:
    def build() -> Tree:
        ib, ob = COMPUTE.bridge_types()
        return Tree(Sequence("compute", children=[ib(name="in"), node(), ob(name="out")]))

    return ros_implementation(name, COMPUTE, build, bridge)


async def test_a_robot_whose_servers_have_another_type_says_why_it_does_not_bid(
    master: Master, servers: Servers, told: Callable[[], list[str]]
) -> None:
    """An action and a service of another type, each said once; a server missing
    altogether is no mismatch (declined unsaid, as before)."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            impls = [
                implementation(
                    "navigate",
                    lambda: RosAction(
                        "go", action_type="move_base_msgs/MoveBase", action_name="count"
                    ),
                    bridge,
                ),
                implementation(
                    "switch",
                    lambda: RosService(
                        "call", service_type="std_srvs/Trigger", service_name="set_flag"
                    ),
                    bridge,
                ),
                implementation(
                    "elsewhere",
                    lambda: RosAction("go", action_type="actionlib/Test", action_name="nowhere"),
                    bridge,
                ),
            ]
            asked = 0
            while len(told()) < 2 or asked < AGAIN:
                asked = asked + 1 if len(told()) >= 2 else 0
                for impl in impls:
                    assert impl.cost(INPUTS) is None, impl.name
                await anyio.sleep(0.02)
    asker = "robot husky1, implementation '{}' of capability Compute"
    assert sorted(told()) == [
        f"{asker.format('navigate')}: action /husky1/count: type mismatch: expected "
        f"move_base_msgs/MoveBase, found actionlib/Test: {DECLINED}",
        f"{asker.format('switch')}: service /husky1/set_flag: type mismatch: expected "
        f"std_srvs/Trigger, found std_srvs/SetBool: {DECLINED}",
    ]
    assert servers.events["count.goal"] == 0
    assert servers.events["set_flag.called"] == 0


async def test_a_cost_reading_a_topic_of_another_type_is_told_once(
    master: Master, servers: Servers, told: Callable[[], list[str]]
) -> None:
    """A distance bid reads the robot's pose (bridge.latest): published as another type,
    none comes and the robot never bids; it is told once why."""
    pose = "geometry_msgs/PoseStamped"
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            asked = 0
            while not told() or asked < AGAIN:
                asked = asked + 1 if told() else 0
                assert bridge.latest(pose, "chatter_out") is None
                await anyio.sleep(0.02)
    assert told() == [
        "RosBridge /husky1/btcap (a cost reads it): topic /husky1/chatter_out: type "
        f"mismatch: expected {pose}, found std_msgs/String: none of that publisher's "
        "messages reach this node"
    ]
