"""A tree node whose action, service or topic has another type on ROS 1 than the node's
says so in one line, naming it, the type it expected and the one it found: rospy only
logs the refused connection, so the node said "no server", failed its call with an md5sum
error, or waited for a message that never comes (servers1.py serves ``count`` as
actionlib/Test, ``set_flag`` as std_srvs/SetBool, publishes ``chatter_out`` as
std_msgs/String)."""

from __future__ import annotations

import anyio
import pytest
from conftest import Servers
from rosmaster1 import Master
from tools1 import FOUND_S, bridge_on, run

from btcap.bt.state import State
from btcap.ros.nodes1 import RosAction, RosService, RosSubscribe, RosWaitForMessage
from btcap.ros.peers1 import service_found

pytestmark = pytest.mark.ros1


async def test_an_action_served_with_another_type_is_said_not_waited_for(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosAction(
                "go",
                action_type="move_base_msgs/MoveBase",
                action_name="count",
                bridge=bridge,
                wait_for_server_timeout=FOUND_S,
            )
            assert await run(node) is State.FAILED
    assert str(node.error) == (
        "RosAction 'go': action /husky1/count: type mismatch: expected "
        "move_base_msgs/MoveBase, found actionlib/Test"
    )
    assert servers.events["count.goal"] == 0


async def test_a_service_of_another_type_is_said_not_called(
    master: Master, servers: Servers
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosService(
                "call",
                service_type="std_srvs/Trigger",
                service_name="set_flag",
                bridge=bridge,
                server_timeout=FOUND_S,
                wait_for_server_timeout=FOUND_S,
            )
            assert await run(node) is State.FAILED
    assert str(node.error) == (
        "RosService 'call': service /husky1/set_flag: type mismatch: expected "
        "std_srvs/Trigger, found std_srvs/SetBool"
    )
    assert servers.events["set_flag.called"] == 0


async def test_a_topic_published_with_another_type_is_said(
    master: Master, servers: Servers
) -> None:
    """A subscriber fails "no message yet" until the type is known, then says it; a wait
    for a message ends at once (none of that publisher's would come)."""
    topic = {"topic_type": "geometry_msgs/PoseStamped", "topic_name": "chatter_out"}
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            latest = RosSubscribe("latest", bridge=bridge, **topic)
            await run(latest, lambda s: "type mismatch" in str(latest.error))
            wait = RosWaitForMessage("wait", bridge=bridge, **topic)
            assert await run(wait) is State.FAILED
    why = (
        "topic /husky1/chatter_out: no message yet: type mismatch: expected "
        "geometry_msgs/PoseStamped, found std_msgs/String"
    )
    assert str(latest.error) == f"RosSubscribe 'latest': {why}"
    assert str(wait.error) == f"RosWaitForMessage 'wait': {why.replace(' yet', '')}"


def test_a_services_probe_header_says_its_type_and_definition() -> None:
    """What a rospy service answers a probe with: its type, and its definition's md5sum,
    which differs for the same type name built from another definition."""
    from std_srvs.srv import SetBool, Trigger

    def header(cls: type) -> dict[str, str]:
        return {"type": cls._type, "md5sum": cls._md5sum, "callerid": "/servers"}

    assert service_found(SetBool, header(SetBool)) == ""
    assert service_found(Trigger, header(SetBool)) == "std_srvs/SetBool"
    other = {**header(SetBool), "md5sum": "0" * 32}
    assert service_found(SetBool, other) == (
        f"std_srvs/SetBool of another definition (md5sum {'0' * 32}; this robot's "
        f"{SetBool._md5sum})"
    )
    assert service_found(SetBool, {"error": "no such service"}) == ""
