"""btcap's own XML-RPC calls to a ROS 1 master (no ROS needed: a real loopback listener
that takes connections and never answers is the stalled master): each is bounded and
fails in one line naming the master and the call, and none runs on an event loop."""

from __future__ import annotations

import socket

import anyio
import pytest

from btcap.ros.errors import RosError
from btcap.ros.rpc1 import RosCallError, call


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
