"""btcap's own XML-RPC calls to a ROS 1 master (no ROS needed: a real loopback listener
that takes connections and never answers is the stalled master): each is bounded and
fails in one line naming the master and the call, and none runs on an event loop."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
import xmlrpc.client

import anyio
import pytest

from btcap.ros.errors import RosError
from btcap.ros.rpc1 import RosCallError, call


def _request(conn: socket.socket) -> None:
    """Read a whole XML-RPC request (before answering it)."""
    data = b""
    while b"</methodCall>" not in data and (chunk := conn.recv(65536)):
        data += chunk


def _silent() -> socket.socket:
    """A listener on loopback whose connections the kernel takes and nobody answers."""
    return socket.create_server(("127.0.0.1", 0), backlog=16)


async def test_a_master_that_never_answers_fails_the_call_in_one_line() -> None:
    with _silent() as listener, anyio.fail_after(20):
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}/"
        with pytest.raises(RosCallError) as err:
            await anyio.to_thread.run_sync(
                lambda: call(uri, "lookupService", "/me", "/x", timeout_s=0.2)
            )
    assert str(err.value) == f"ROS 1 master {uri}: lookupService: no answer within 0.2 s"
    assert err.value.stalled
    assert not err.value.answered


async def test_a_call_on_the_event_loop_is_refused_before_it_connects() -> None:
    with _silent() as listener:
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}/"
        with pytest.raises(RosError) as err:
            call(uri, "getPid", "/me")
        listener.setblocking(False)
        with pytest.raises(BlockingIOError):  # nothing connected: it never tried
            listener.accept()
    assert str(err.value) == (
        f"ROS 1 master {uri}: getPid called on the event loop's thread (it blocks up to "
        "its timeout): run it in a thread"
    )
    assert not isinstance(err.value, RosCallError)


async def test_an_answer_sent_a_byte_at_a_time_is_bounded_as_a_whole() -> None:
    """A peer that trickles its answer (each byte well within the timeout) holds the call
    no longer than the timeout: the bound is the call's, not each read's."""
    body = xmlrpc.client.dumps(([1, "ok", 42],), methodresponse=True).encode()
    answer = b"HTTP/1.0 200 OK\r\nContent-Type: text/xml\r\n\r\n" + body

    def trickle(listener: socket.socket) -> None:
        conn, _ = listener.accept()
        with conn, contextlib.suppress(OSError):  # the caller hung up: done
            _request(conn)
            for byte in answer:
                conn.sendall(bytes([byte]))
                time.sleep(0.05)

    with _silent() as listener, anyio.fail_after(60):
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}/"
        peer = threading.Thread(target=trickle, args=(listener,))
        peer.start()
        try:
            with pytest.raises(RosCallError) as err:
                await anyio.to_thread.run_sync(lambda: call(uri, "getPid", "/me", timeout_s=0.5))
        finally:
            await anyio.to_thread.run_sync(peer.join)
    assert str(err.value) == f"ROS 1 master {uri}: getPid: no answer within 0.5 s"
    assert err.value.stalled


async def test_an_answer_within_the_bound_is_read() -> None:
    """The bounded socket reads a whole answer (as a master's, sent at once)."""
    body = xmlrpc.client.dumps(([1, "ok", 42],), methodresponse=True).encode()
    answer = b"HTTP/1.0 200 OK\r\nContent-Type: text/xml\r\n\r\n" + body

    def serve(listener: socket.socket) -> None:
        conn, _ = listener.accept()
        with conn:
            _request(conn)
            conn.sendall(answer)

    with _silent() as listener, anyio.fail_after(20):
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}/"
        peer = threading.Thread(target=serve, args=(listener,))
        peer.start()
        try:
            value = await anyio.to_thread.run_sync(lambda: call(uri, "getPid", "/me"))
        finally:
            await anyio.to_thread.run_sync(peer.join)
    assert value == 42
