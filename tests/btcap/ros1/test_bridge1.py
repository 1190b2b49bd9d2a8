"""The ROS 1 bridge's life: a master that does not answer is one line and starts nothing;
closing cancels open goals and leaves no process, thread or registration; a second node
taking the robot's name fails the first robot's nodes saying why."""

from __future__ import annotations

import socket
import threading

import anyio
import pytest
from conftest import Servers
from rosmaster1 import Master, free_port
from tools1 import FOUND_S, bridge_on, registered, run, settle

from btcap.bt.state import State
from btcap.ros.client1 import Ros1Bridge
from btcap.ros.errors import RosError
from btcap.ros.nodes1 import RosAction
from btcap.team.rossettings import RosSettings

pytestmark = pytest.mark.ros1


async def test_an_unreachable_master_is_one_line_and_starts_nothing() -> None:
    uri = f"http://127.0.0.1:{free_port()}/"
    bridge = Ros1Bridge(RosSettings(backend="ros1", master_uri=uri), robot="husky1")
    with anyio.fail_after(20), pytest.raises(RosError) as err:
        await bridge.__aenter__()
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"ROS 1 master {uri} does not answer getPid (")
    assert "Connection refused" in line
    assert bridge.process is None
    assert bridge.node is None
    await bridge.__aexit__(None, None, None)


async def test_closing_cancels_open_goals_and_leaves_nothing_behind(
    master: Master, servers: Servers
) -> None:
    before = registered(master)
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosAction(
                "act",
                action_type="actionlib/Test",
                action_name="count",
                bridge=bridge,
                inputs={"goal": -2},
                server_timeout=FOUND_S,
            )
            await run(node, lambda s: node.outputs["feedback_feedback"] is not None)
            assert any("/husky1/btcap" in r for r in registered(master))
            process = bridge.process
            threads = [t.name for t in threading.enumerate() if t.name.startswith("btcap-ros")]
            assert sorted(threads) == ["btcap-ros1-writer/husky1/btcap", "btcap-ros1/husky1/btcap"]
        await settle(lambda: servers.events["count.preempted"] == 1)
    assert process is not None
    assert process.returncode == 0
    assert registered(master) == before
    assert [t.name for t in threading.enumerate() if t.name.startswith("btcap-ros")] == []
    with pytest.raises(RosError, match="closed"):
        bridge.running()


async def test_a_second_node_taking_the_robots_name_fails_the_first_saying_why(
    master: Master,
) -> None:
    with anyio.fail_after(30):
        async with bridge_on(master) as first, bridge_on(master):
            await settle(lambda: first.conflict is not None)
            node = RosAction("act", action_type="actionlib/Test", action_name="count", bridge=first)
            assert await run(node) is State.ERROR
    line = str(node.error)
    assert "\n" not in line
    assert "the ROS 1 node /husky1/btcap was shut down: " in line
    assert "new node registered with same name" in line


async def test_a_process_default_socket_timeout_does_not_break_the_pipe(
    master: Master, servers: Servers
) -> None:
    """rospy (in a process that is also a ROS 1 node) sets socket.setdefaulttimeout: the
    bridge's socket pair would then be non-blocking and its reader end at once."""
    old = socket.getdefaulttimeout()
    socket.setdefaulttimeout(5.0)
    try:
        with anyio.fail_after(30):
            async with bridge_on(master) as bridge:
                node = RosAction(
                    "act",
                    action_type="actionlib/Test",
                    action_name="count",
                    bridge=bridge,
                    inputs={"goal": 2},
                    server_timeout=FOUND_S,
                )
                assert await run(node) is State.SUCCEEDED, node.error
    finally:
        socket.setdefaulttimeout(old)


async def test_a_rospy_process_that_dies_fails_every_node_at_once_saying_so(
    master: Master, servers: Servers
) -> None:
    """Killed (or crashed) under a running bridge: the robot's ROS nodes fail at their
    next tick naming it, not after wait_for_server_timeout as if their servers had gone."""
    with anyio.fail_after(30):
        async with bridge_on(master) as bridge:
            node = RosAction(
                "act",
                action_type="actionlib/Test",
                action_name="count",
                bridge=bridge,
                inputs={"goal": -2},
                server_timeout=FOUND_S,
            )
            await run(node, lambda s: node.outputs["feedback_feedback"] is not None)
            assert bridge.process is not None
            bridge.process.kill()
            assert await run(node) is State.FAILED
            assert "its rospy process ended" in str(node.error)
            again = RosAction(
                "again",
                action_type="actionlib/Test",
                action_name="count",
                bridge=bridge,
                inputs={"goal": 1},
                wait_for_server_timeout=FOUND_S,
            )
            assert await run(again) is State.ERROR
    assert str(again.error) == (
        "node 'again': the ROS 1 node /husky1/btcap's rospy process ended unasked (exit "
        "code -9): restart the robot's agent (or make a new Ros1Bridge)"
    )


async def test_a_restarted_master_is_said_once_with_what_it_means(master: Master) -> None:
    """rospy never registers again with a new master, so what was registered before is
    unknown to it: the bridge says so in one warning, not only through servers that look
    gone."""
    from structlog.testing import capture_logs

    with anyio.fail_after(30), capture_logs() as logs:
        async with bridge_on(master):
            await anyio.to_thread.run_sync(master.stop)
            await anyio.to_thread.run_sync(master.start)  # the same port, a new pid
            await settle(lambda: any(e["event"] == "btcap.ros1.notice" for e in logs))
    (notice,) = [e for e in logs if e["event"] == "btcap.ros1.notice"]
    assert notice["why"].startswith(f"the ROS 1 master {master.uri} restarted (pid ")
    assert "\n" not in notice["why"]
