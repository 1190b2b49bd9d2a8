"""RosService, RosPublish, RosSubscribe and RosWaitForMessage against real ROS 2 nodes."""

from __future__ import annotations

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, tick_until, tree_of

from btcap.bt.composites import Parallel
from btcap.bt.state import State
from btcap.ros.client import RosBridge
from btcap.ros.service import RosService
from btcap.ros.topic import RosPublish, RosSubscribe, RosWaitForMessage

pytestmark = pytest.mark.ros

SET_BOOL = "std_srvs/srv/SetBool"
STRING = "std_msgs/msg/String"


async def test_a_service_call_puts_the_response_in_the_outputs(
    servers: Servers, bridge: RosBridge
) -> None:
    node = RosService(
        "call",
        service_type=SET_BOOL,
        service_name="set_bool",
        bridge=bridge,
        inputs={"data": True},
        server_timeout=FOUND_S,
    )
    with anyio.fail_after(10):
        state = await tick_until(tree_of(node))
    assert state is State.SUCCEEDED, node.error
    assert node.outputs == {"success": True, "message": "data was True"}


async def test_a_slow_service_fails_at_server_timeout_saying_so(
    servers: Servers, bridge: RosBridge
) -> None:
    node = RosService(
        "call",
        service_type=SET_BOOL,
        service_name="set_bool_slow",
        server_timeout=0.3,
        bridge=bridge,
        inputs={"data": True},
    )
    with anyio.fail_after(10):
        state = await tick_until(tree_of(node))
    assert state is State.FAILED
    assert "service /husky1/set_bool_slow (std_srvs/srv/SetBool): no response within" in str(
        node.error
    )


async def test_publish_and_subscribe_round_trip_through_another_node(
    servers: Servers, bridge: RosBridge
) -> None:
    """RosPublish at 50 Hz to echo_in; the servers' node echoes it upper-cased on
    echo_out, which RosWaitForMessage waits for and RosSubscribe then holds."""
    pub = RosPublish(
        "pub", topic_type=STRING, topic_name="echo_in", rate_hz=50.0, inputs={"data": "hi"}
    )
    wait = RosWaitForMessage("wait", topic_type=STRING, topic_name="/husky1/echo_out")
    for n in (pub, wait):
        n._bridge = bridge
    root = Parallel("both", children=[pub, wait], success_threshold=1)
    with anyio.fail_after(10):
        state = await tick_until(tree_of(root))
    assert state is State.SUCCEEDED
    assert wait.outputs == {"message": {"data": "HI"}, "data": "HI"}
    latest = RosSubscribe(
        "latest", topic_type=STRING, topic_name="echo_out", fields=["data"], max_age=5.0
    )
    latest._bridge = bridge
    again = RosPublish(
        "again", topic_type=STRING, topic_name="echo_in", rate_hz=50.0, inputs={"data": "yo"}
    )
    again._bridge = bridge
    subscribed, publishing = tree_of(latest), tree_of(again)
    silent = RosSubscribe("silent", topic_type=STRING, topic_name="nobody_publishes")
    silent._bridge = bridge
    assert tree_of(silent).tick() is State.FAILED
    assert (
        str(silent.error) == "RosSubscribe 'silent': topic /husky1/nobody_publishes: no message yet"
    )
    with anyio.fail_after(10):  # echoes of "hi" may still be on their way: until "YO"
        while subscribed.tick() is not State.SUCCEEDED or latest.outputs["data"] != "YO":
            assert publishing.tick() is State.RUNNING
            await anyio.sleep(0.005)
    assert latest.outputs == {"message": {"data": "YO"}, "data": "YO"}
