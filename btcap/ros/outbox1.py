"""The frames a robot's ROS 1 bridge writes to its rospy process (:mod:`btcap.ros.child1`),
without ever waiting on it: the tick writes them.

The rospy process reads frames on one thread, which can stall: rospy retries registering
a new publisher or client with a master that is gone until one answers, and meanwhile
reads nothing. A blocking write from the tick would then hold the event loop as soon as
the socket's buffer is full (a few large messages). So :meth:`Outbox.put` writes a frame
at once only when the socket takes all of it without waiting and nothing is queued before
it; otherwise the frame joins a queue that a writer thread of its own writes, in order.
While frames wait, a publisher keeps at most its queue size of messages, dropping the
oldest, as rospy's own publisher queue does; goals, cancels, calls and the rest are never
dropped. The framing is :class:`multiprocessing.connection.Connection`'s, which the rospy
process reads with.
"""

from __future__ import annotations

import collections
import socket
import struct
import threading

__all__ = ["Outbox"]

_HEADER = struct.Struct("!i")
#: Connection's framing of a frame of 2 GiB or more: -1, then an 8-byte length.
_LONG = struct.Struct("!iQ")


def _framed(data: bytes) -> bytes:
    n = len(data)
    head = _HEADER.pack(n) if n <= 0x7FFFFFFF else _LONG.pack(-1, n)
    return head + data


class _Entry:
    __slots__ = ("cid", "data", "dropped")

    def __init__(self, data: bytes, cid: int | None) -> None:
        self.data, self.cid, self.dropped = data, cid, False


class Outbox:
    """Frames to ``sock`` (a blocking socket), in order, never blocking :meth:`put`."""

    def __init__(self, sock: socket.socket, name: str) -> None:
        self.sock = sock
        self._queue: collections.deque[_Entry] = collections.deque()
        self._pending: dict[int, collections.deque[_Entry]] = {}  # a publisher's, by cid
        self._cv = threading.Condition()
        self._writing = False
        self._closed = False
        #: Why writing failed (the process is gone), once it did.
        self.error: OSError | None = None
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def put(self, data: bytes, cid: int | None = None, depth: int = 0) -> None:
        """Write frame ``data`` now if the socket takes it whole, else queue it; a publish
        to publisher ``cid`` keeps at most ``depth`` queued (OSError once writing failed)."""
        framed = _framed(data)
        with self._cv:
            if self.error is not None:
                raise self.error
            if not self._queue and not self._writing:
                try:
                    sent = self.sock.send(framed, socket.MSG_DONTWAIT)
                except BlockingIOError:
                    sent = 0
                except OSError as exc:
                    self.error = exc
                    raise
                if sent == len(framed):
                    return
                self._queue.append(_Entry(framed[sent:], None))  # the rest goes first
                cid = None  # begun: never dropped
                framed = b""
            if framed:
                entry = _Entry(framed, cid)
                self._queue.append(entry)
                if cid is not None:
                    waiting = self._pending.setdefault(cid, collections.deque())
                    waiting.append(entry)
                    while len(waiting) > max(depth, 1):
                        waiting.popleft().dropped = True
            self._cv.notify()

    def waiting(self) -> int:
        """How many frames wait to be written."""
        with self._cv:
            return sum(not e.dropped for e in self._queue)

    def _run(self) -> None:  # the writer thread
        while True:
            with self._cv:
                while not self._queue and not self._closed:
                    self._cv.wait()
                if not self._queue:
                    return
                entry = self._queue.popleft()
                if entry.cid is not None:
                    waiting = self._pending.get(entry.cid)
                    if waiting and waiting[0] is entry:
                        waiting.popleft()
                        if not waiting:  # (a publisher is opened per run: none stays)
                            del self._pending[entry.cid]
                if entry.dropped:
                    continue
                self._writing = True
            try:
                self.sock.sendall(entry.data)
            except OSError as exc:
                with self._cv:
                    self.error = exc
                    self._writing = False
                    self._queue.clear()
                    self._pending.clear()
                return
            with self._cv:
                self._writing = False

    def close(self, timeout: float) -> None:
        """Write what is queued (``timeout`` seconds at most: then the process is killed
        or gone, which ends the write), then end the writer thread."""
        with self._cv:
            self._closed = True
            self._cv.notify()
        self._thread.join(timeout)
