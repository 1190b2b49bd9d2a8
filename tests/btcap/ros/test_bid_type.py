"""A robot whose only server for a ROS capability implementation has another type declines
to bid, and says so once, naming the robot, the implementation and its capability, the
name and both types (rosservers.py serves ``fibonacci`` as test_msgs/action/Fibonacci and
``set_bool`` as std_srvs/srv/SetBool). Before, its bid was just None: the robot never took
the task, and nobody was told why."""

from __future__ import annotations

import time
from collections.abc import Callable

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S

from btcap.bt.composites import Sequence
from btcap.bt.node import Node
from btcap.bt.tree import Tree
from btcap.ros import peers
from btcap.ros.action import RosAction
from btcap.ros.capability import ros_implementation
from btcap.ros.client import RosBridge
from btcap.ros.service import RosService
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation

pytestmark = pytest.mark.ros

COMPUTE = CapabilityInterface(
    "Compute",
    inputs={"order": int},
    outputs={},
    description="something the robot's ROS server does",
)
INPUTS = {"order": 3}
DECLINED = "it declines to bid until a server of its type answers"


def implementation(name: str, node: Callable[[], Node], bridge: RosBridge) -> Implementation:
    """``name``, made of ``node()`` between the capability's bridges, bidding over ROS."""

    def build() -> Tree:
        ib, ob = COMPUTE.bridge_types()
        return Tree(Sequence("compute", children=[ib(name="in"), node(), ob(name="out")]))

    return ros_implementation(name, COMPUTE, build, bridge)


async def declines(
    bridge: RosBridge, told: Callable[[], list[str]], *impls: Implementation
) -> None:
    """Ask each of ``impls`` for bids (as every call for bids does: none bids) until one
    told why it declines and the graph was read twice more since (a second line would have
    come by then)."""
    assert bridge._peers is not None
    since = None
    while since is None or bridge._peers.checks < since + 2:
        for impl in impls:
            assert impl.cost(INPUTS) is None
        if since is None and told():
            since = bridge._peers.checks
        await anyio.sleep(0.01)


async def test_a_robot_whose_action_server_has_another_type_says_why_it_does_not_bid(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """Said once however often it is asked, the graph read at most every CHECK_S (on the
    bridge's thread, never at each bid). A server missing altogether is no mismatch: the
    implementation that needs one declines unsaid, as before."""
    wrong = implementation(
        "compute-nested",
        lambda: RosAction(
            "go", action_type="test_msgs/action/NestedMessage", action_name="fibonacci"
        ),
        bridge,
    )
    missing = implementation(
        "compute-elsewhere",
        lambda: RosAction("fib", action_type="test_msgs/action/Fibonacci", action_name="nowhere"),
        bridge,
    )
    started = time.monotonic()
    with anyio.fail_after(3 * FOUND_S):
        await declines(bridge, told, wrong, missing)
    assert told() == [
        "robot husky1, implementation 'compute-nested' of capability Compute: action "
        "/husky1/fibonacci: type mismatch: expected test_msgs/action/NestedMessage, found "
        f"test_msgs/action/Fibonacci: {DECLINED}"
    ]
    assert bridge._peers is not None
    assert bridge._peers.checks <= 4 + 2 * (time.monotonic() - started) / peers.CHECK_S
    assert servers.events["fibonacci.accepted"] == 0


async def test_a_robot_whose_service_has_another_type_says_why_it_does_not_bid(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    impl = implementation(
        "switch",
        lambda: RosService("call", service_type="std_srvs/srv/Trigger", service_name="set_bool"),
        bridge,
    )
    with anyio.fail_after(3 * FOUND_S):
        await declines(bridge, told, impl)
    assert told() == [
        "robot husky1, implementation 'switch' of capability Compute: service "
        "/husky1/set_bool: type mismatch: expected std_srvs/srv/Trigger, found "
        f"std_srvs/srv/SetBool: {DECLINED}"
    ]
    assert servers.events["set_bool"] == 0
