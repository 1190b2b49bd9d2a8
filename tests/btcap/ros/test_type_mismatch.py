"""A ROS 2 tree node whose peer on its name has another type says so, once, naming the
node, the name, the type it expected and the one found, and a goal, call or wait that
can never be answered fails then instead of at its timeout (rosservers.py serves
``fibonacci`` as test_msgs/action/Fibonacci and ``set_bool`` as std_srvs/srv/SetBool,
publishes ``echo_out`` and subscribes ``echo_in`` as std_msgs/msg/String). Before, ROS 2's
graph was never asked: such a node said "no server" after ``wait_for_server_timeout``,
or "no message yet", and a publisher said nothing at all."""

from __future__ import annotations

import time
from collections.abc import Callable

import anyio
import pytest
from rosservers import Servers
from rostools import FOUND_S, tick_until, tree_of, wait_for

from btcap.bt.state import State
from btcap.ros import peers
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.ros.service import RosService
from btcap.ros.topic import RosPublish, RosSubscribe, RosWaitForMessage

pytestmark = pytest.mark.ros

POSE = "geometry_msgs/msg/PoseStamped"


async def test_an_action_served_with_another_type_fails_saying_so(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    node = RosAction(
        "go",
        action_type="test_msgs/action/NestedMessage",
        action_name="fibonacci",
        bridge=bridge,
        wait_for_server_timeout=FOUND_S,
    )
    with anyio.fail_after(2 * FOUND_S):  # without the check: "no server" at FOUND_S
        assert await tick_until(tree_of(node)) is State.FAILED
    why = (
        "RosAction 'go': action /husky1/fibonacci: type mismatch: expected "
        "test_msgs/action/NestedMessage, found test_msgs/action/Fibonacci"
    )
    assert str(node.error) == why
    assert told() == [f"{why}: an action server of that type never answers this node's goals"]
    assert servers.events["fibonacci.accepted"] == 0


async def test_a_service_of_another_type_fails_saying_so(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    node = RosService(
        "call",
        service_type="std_srvs/srv/Trigger",
        service_name="set_bool",
        bridge=bridge,
        wait_for_server_timeout=FOUND_S,
    )
    with anyio.fail_after(2 * FOUND_S):  # without the check: "no server" at FOUND_S
        assert await tick_until(tree_of(node)) is State.FAILED
    why = (
        "RosService 'call': service /husky1/set_bool: type mismatch: expected "
        "std_srvs/srv/Trigger, found std_srvs/srv/SetBool"
    )
    assert str(node.error) == why
    assert told() == [f"{why}: a service server of that type never answers this node's calls"]
    assert servers.events["set_bool"] == 0


async def test_a_client_of_another_type_is_no_server_of_it(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """Only a client of SetBool on ``lonely`` (listed by the graph among the service's
    types): no server at all, so the node waits its timeout and says "no server"."""
    from std_srvs.srv import SetBool

    servers.node.create_client(SetBool, "lonely")
    with anyio.fail_after(FOUND_S):
        await wait_for(lambda: bridge.node.count_clients("/husky1/lonely") == 1)
    node = RosService(
        "call",
        service_type="std_srvs/srv/Trigger",
        service_name="lonely",
        bridge=bridge,
        wait_for_server_timeout=1.0,
    )
    with anyio.fail_after(FOUND_S):
        assert await tick_until(tree_of(node)) is State.FAILED
    assert str(node.error) == (
        "RosService 'call': service /husky1/lonely (std_srvs/srv/Trigger): no server within "
        "wait_for_server_timeout 1.0 s"
    )
    assert bridge._peers is not None
    assert bridge._peers.checks >= 1
    assert told() == []


async def test_a_topic_published_with_another_type_is_said(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """A subscriber fails "no message yet" until the type is known, then says it; a wait
    for a message ends at once (none of that publisher's would come). Each node is told
    once."""
    topic = {"topic_type": POSE, "topic_name": "echo_out", "bridge": bridge}
    latest = RosSubscribe("latest", **topic)
    wait = RosWaitForMessage("wait", **topic)
    with anyio.fail_after(FOUND_S):
        await tick_until(tree_of(latest), lambda s: "type mismatch" in str(latest.error))
        assert await tick_until(tree_of(wait)) is State.FAILED
    why = (
        "topic /husky1/echo_out: no message yet: type mismatch: expected "
        f"{POSE}, found std_msgs/msg/String"
    )
    assert latest.state is State.FAILED
    assert str(latest.error) == f"RosSubscribe 'latest': {why}"
    assert str(wait.error) == f"RosWaitForMessage 'wait': {why.replace(' yet', '')}"
    effect = "none of that publisher's messages reach this node"
    assert sorted(told()) == [
        f"RosSubscribe 'latest': topic /husky1/echo_out: type mismatch: expected {POSE}, "
        f"found std_msgs/msg/String: {effect}",
        f"RosWaitForMessage 'wait': topic /husky1/echo_out: type mismatch: expected {POSE}, "
        f"found std_msgs/msg/String: {effect}",
    ]


async def test_a_publisher_is_told_of_a_subscriber_of_another_type_once(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """It still publishes (RUNNING at its rate): a subscriber of its own type would get
    its messages. The graph is read at its first tick and then at most every CHECK_S,
    however often it ticks, and it is told once."""
    node = RosPublish("pub", topic_type=POSE, topic_name="echo_in", rate_hz=200.0, bridge=bridge)
    tree = tree_of(node)
    started = time.monotonic()
    assert bridge._peers is not None
    with anyio.fail_after(2 * FOUND_S):
        while not told() or bridge._peers.checks < 3:
            assert tree.tick() is State.RUNNING
            await anyio.sleep(0.002)
    elapsed = time.monotonic() - started
    assert told() == [
        f"RosPublish 'pub': topic /husky1/echo_in: type mismatch: expected {POSE}, found "
        "std_msgs/msg/String: none of this node's messages reach that subscriber"
    ]
    # At the first question, then at most once per CHECK_S (fewer on a loaded machine),
    # not at each of its ticks (a tick every 2 ms or so).
    assert bridge._peers.checks <= 2 + elapsed / peers.CHECK_S


async def test_peers_of_the_nodes_own_type_are_no_mismatch(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """A goal to a server of the node's type succeeds, unsaid; a wait on a topic published
    with another type and with the node's own gets the message of its own type (another
    type beside its own may be told, but fails nothing)."""
    goal = RosAction(
        "go",
        action_type="test_msgs/action/Fibonacci",
        action_name="fibonacci",
        bridge=bridge,
        server_timeout=FOUND_S,
        inputs={"order": 3},
    )
    with anyio.fail_after(FOUND_S):
        assert await tick_until(tree_of(goal)) is State.SUCCEEDED, goal.error
    assert told() == []
    from std_msgs.msg import String

    servers.node.create_publisher(String, "mixed", 10)
    node = RosPublish("pub", topic_type=POSE, topic_name="mixed", bridge=bridge, rate_hz=50.0)
    wait = RosWaitForMessage("wait", topic_type=POSE, topic_name="mixed", bridge=bridge)
    publishing, waiting = tree_of(node), tree_of(wait)
    with anyio.fail_after(FOUND_S):
        while waiting.tick() is State.RUNNING:
            assert publishing.tick() is State.RUNNING
            await anyio.sleep(0.005)
    assert wait.state is State.SUCCEEDED, wait.error
    assert all("RosWaitForMessage 'wait'" in line for line in told())


async def test_a_cost_reading_a_topic_of_another_type_is_told(
    servers: Servers, bridge: RosBridge, told: Callable[[], list[str]]
) -> None:
    """A distance bid reads the robot's pose (bridge.latest): published as another type,
    none comes and the robot never bids; it is told once why."""
    from std_msgs.msg import String

    servers.node.create_publisher(String, "odom", 10)
    with anyio.fail_after(FOUND_S):
        while not told():
            assert bridge.latest(POSE, "odom") is None
            await anyio.sleep(0.01)
        assert bridge.latest(POSE, "odom") is None
    assert told() == [
        "RosBridge /husky1/btcap (a cost reads it): topic /husky1/odom: type mismatch: "
        f"expected {POSE}, found std_msgs/msg/String: none of that publisher's messages "
        "reach this node"
    ]
