"""The types of a ROS 1 client's peers (btcap.ros.peers1): a service server slow to answer
its probe once is read again (a timeout is no verdict), definite answers are kept for a
bounded number of servers, and a topic with publishers of two types (the master names
one) fails a subscriber of neither: the one of its own type is waited for, the other
noted in one line."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import anyio
import pytest
from conftest import Servers
from rosmaster1 import READY_S, Master
from structlog.testing import capture_logs
from tools1 import FOUND_S, bridge_on, run, settle

from btcap.bt.state import State
from btcap.ros.nodes1 import RosService, RosWaitForMessage
from btcap.ros.peers1 import KEPT, RETRY_S, PeerTypes, peers_found

pytestmark = pytest.mark.ros1


@contextmanager
def stopped(pid: int) -> Iterator[None]:
    """Process ``pid`` stopped (SIGSTOP): its sockets take connections, nothing answers."""
    os.kill(pid, signal.SIGSTOP)
    try:
        yield
    finally:
        os.kill(pid, signal.SIGCONT)


@contextmanager
def talker(master: Master, node: str, type_name: str, topic: str) -> Iterator[int]:
    """tests/btcap/ros1/talkers1.py publishing ``topic`` in /husky1, registered; its pid."""
    env = dict(master.env(), ROS_NAMESPACE="/husky1")
    script = str(Path(__file__).with_name("talkers1.py"))
    process = subprocess.Popen(
        [sys.executable, script, node, type_name, topic],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdin is not None
    assert process.stdout is not None
    try:
        assert process.stdout.readline().strip() == "up"
        yield process.pid
    finally:
        os.kill(process.pid, signal.SIGCONT)
        process.stdin.close()
        try:
            process.wait(timeout=READY_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        process.stdout.close()


async def test_a_service_slow_to_answer_its_probe_once_is_read_again(
    master: Master, servers: Servers
) -> None:
    """The servers' process is stopped while the client's first probe waits for its
    header (the probe connects and is written: the client counts as ready); once it goes
    on, its header says its type. A timed-out read was kept as "nothing found" for good,
    and the call then failed with rospy's md5sum error."""
    with anyio.fail_after(45):
        async with bridge_on(master) as bridge:
            with stopped(servers.process.pid):
                client = bridge.service_client("std_srvs/Trigger", "set_flag")
                await settle(lambda: client.ready)  # its first probe read no header
                assert client.mismatch is None
            await settle(lambda: client.mismatch is not None)
            node = RosService(
                "call",
                service_type="std_srvs/Trigger",
                service_name="set_flag",
                bridge=bridge,
                server_timeout=FOUND_S,
            )
            assert await run(node) is State.FAILED
    assert str(node.error) == (
        "RosService 'call': service /husky1/set_flag: type mismatch: expected "
        "std_srvs/Trigger, found std_srvs/SetBool"
    )
    assert servers.events["set_flag.called"] == 0


def _header(sock: socket.socket, cls: type) -> None:
    import rosgraph.network

    fields = {"type": cls._type, "md5sum": cls._md5sum, "callerid": "/servers"}  # type: ignore[attr-defined]
    rosgraph.network.write_ros_handshake_header(sock, fields)


def test_only_a_definite_header_is_kept_and_for_a_bounded_number_of_servers() -> None:
    """Real sockets, rospy's own header codec: a read that timed out gives nothing and
    is tried again RETRY_S later; a header read is kept, for at most KEPT servers."""
    from std_srvs.srv import SetBool, Trigger

    from btcap.ros.interfaces1 import interface1

    now = [0.0]
    peers = PeerTypes("/me", ask=lambda *a: None, clock=lambda: now[0])
    types = interface1("std_srvs/Trigger", "srv")
    ours, theirs = socket.socketpair()
    with ours, theirs:
        ours.settimeout(0.05)
        assert peers.service(types, "rosrpc://slow:1", ours) == ""  # no header yet
        _header(theirs, SetBool)
        assert peers.service(types, "rosrpc://slow:1", ours) == ""  # not read before RETRY_S
        now[0] += RETRY_S
        assert peers.service(types, "rosrpc://slow:1", ours) == "std_srvs/SetBool"
        assert peers.service(types, "rosrpc://slow:1", ours) == "std_srvs/SetBool"  # kept
    for i in range(KEPT + 20):
        ours, theirs = socket.socketpair()
        with ours, theirs:
            _header(theirs, SetBool if i % 2 else Trigger)
            expected = "std_srvs/SetBool" if i % 2 else ""
            assert peers.service(types, f"rosrpc://s:{i}", ours) == expected
    assert len(peers._verdicts) == KEPT
    assert len(peers._retry) == 0


def test_a_peer_of_its_own_type_is_never_said_mismatched() -> None:
    ours = "std_msgs/String"
    assert peers_found(ours, {}, False) == ("", "")
    assert peers_found(ours, {"/a": "std_msgs/Int32"}, False) == ("std_msgs/Int32", "")
    two = {"/a": "std_msgs/Int32", "/b": "std_msgs/Bool"}
    assert peers_found(ours, two, False) == ("std_msgs/Bool, std_msgs/Int32", "")
    mixed = {"/a": "std_msgs/Int32", "/b": ours}
    assert peers_found(ours, mixed, False) == ("", "/a (std_msgs/Int32)")
    unknown = {"/a": "std_msgs/Int32", "/b": None}  # /b did not say: maybe its own
    assert peers_found(ours, unknown, False) == ("", "/a (std_msgs/Int32)")
    assert peers_found(ours, {"/a": "std_msgs/Int32"}, True) == ("", "/a (std_msgs/Int32)")
    assert peers_found(ours, {"/a": "*"}, False) == ("", "")


async def test_a_topic_of_two_types_waits_for_its_own_and_notes_the_other(
    master: Master,
) -> None:
    """``mixed`` published as std_msgs/String by ``mine`` (stopped: no connection yet),
    then as std_msgs/Int32 by ``theirs``: the master names Int32. A wait for a String
    failed at once saying Int32; it waits for ``mine``, gets its message once it goes on,
    and ``theirs`` is said once."""
    topic = {"topic_type": "std_msgs/String", "topic_name": "mixed"}
    with (
        anyio.fail_after(45),
        capture_logs() as logs,
        talker(master, "mine", "std_msgs/String", "mixed") as mine,
        talker(master, "theirs", "std_msgs/Int32", "mixed"),
    ):
        with master.proxy() as proxy:
            assert ["/husky1/mixed", "std_msgs/Int32"] in proxy.getPublishedTopics("/t", "")[2]

        def noted() -> list[str]:
            return [e["why"] for e in logs if e["event"] == "btcap.ros1.notice"]

        async with bridge_on(master) as bridge:
            wait = RosWaitForMessage("wait", bridge=bridge, **topic)
            with stopped(mine):
                state = await run(wait, lambda s: s is not State.RUNNING or bool(noted()))
                assert state is State.RUNNING, wait.error
            assert await run(wait) is State.SUCCEEDED, wait.error
    assert noted() == [
        "topic /husky1/mixed: publishers of another type than this robot's std_msgs/String "
        "(it cannot connect to them): /husky1/theirs (std_msgs/Int32)"
    ]
