"""The ROS 1 bridge's outbox (no ROS: a socket pair stands for the rospy process's pipe):
frames that wait while the process reads nothing are written in order once it reads
again, and a publisher's bookkeeping goes with its last waiting frame (a publisher is
opened per run of a node, so what stayed of each would grow for the robot's life)."""

from __future__ import annotations

import socket
import threading

from btcap.ros.outbox1 import Outbox

FRAMES = 40
SIZE = 100_000  # far more than the socket buffer holds, together


def _read(sock: socket.socket, n: int, into: bytearray) -> None:
    while len(into) < n:
        chunk = sock.recv(1 << 16)
        if not chunk:
            return
        into.extend(chunk)


def test_waiting_frames_are_written_in_order_and_leave_no_publisher_behind() -> None:
    ours, theirs = socket.socketpair()
    with ours, theirs:
        outbox = Outbox(ours, "test-outbox")
        try:
            for cid in range(1, FRAMES + 1):  # one message each of many publishers
                outbox.put(bytes([cid]) * SIZE, cid, 1)
            assert outbox.waiting() > 0  # nobody read yet: they wait
            got = bytearray()
            expected = FRAMES * (4 + SIZE)
            reader = threading.Thread(target=_read, args=(theirs, expected, got))
            reader.start()
            reader.join(30)
            assert len(got) == expected
            assert [got[i * (4 + SIZE) + 4] for i in range(FRAMES)] == list(range(1, FRAMES + 1))
        finally:
            outbox.close(timeout=5)
        assert outbox.waiting() == 0
        assert outbox._pending == {}  # no publisher's queue stays once written
