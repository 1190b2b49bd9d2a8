"""Topics whose publisher offers a QoS the node does not accept (a sensor's best-effort
stream, the bridge's reliable default): no message ever arrives, and the node says why
instead of "no message yet"; with the node's QoS set to match, the messages come."""

from __future__ import annotations

import anyio
import pytest
from rosservers import Servers
from rostools import tick_until, tree_of

from btcap.bt.state import State
from btcap.ros.client import RosBridge
from btcap.ros.topic import RosSubscribe, RosWaitForMessage

pytestmark = pytest.mark.ros

STRING = "std_msgs/msg/String"


@pytest.fixture
def best_effort(servers: Servers) -> Servers:
    """The servers' node publishes /husky1/scan best-effort at 50 Hz."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub = servers.node.create_publisher(String, "scan", qos)
    servers.scan_timer = servers.node.create_timer(0.02, lambda: pub.publish(String(data="s")))  # type: ignore[attr-defined]
    return servers


async def test_an_incompatible_publisher_is_named_in_the_nodes_error(
    best_effort: Servers, bridge: RosBridge
) -> None:
    node = RosSubscribe("scan", topic_type=STRING, topic_name="scan", bridge=bridge)
    with anyio.fail_after(15):
        await tick_until(tree_of(node), lambda s: "does not accept" in str(node.error))
    assert node.state is State.FAILED
    assert str(node.error) == (
        "RosSubscribe 'scan': topic /husky1/scan: no message yet: a publisher of it offers "
        "a QoS this node does not accept (RELIABILITY), so none of its messages arrive; "
        "set the node's reliability, durability or depth to match"
    )


async def test_with_a_matching_qos_the_messages_come(
    best_effort: Servers, bridge: RosBridge
) -> None:
    node = RosWaitForMessage(
        "scan", topic_type=STRING, topic_name="scan", bridge=bridge, reliability="best_effort"
    )
    with anyio.fail_after(15):
        state = await tick_until(tree_of(node))
    assert state is State.SUCCEEDED, node.error
    assert node.outputs["data"] == "s"
