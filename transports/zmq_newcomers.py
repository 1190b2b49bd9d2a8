"""Closing the inbound connections of a ZeroMQ transport's ROUTER that say no hello
(what to close: :class:`~btcap.transports.newcomers.Newcomers`).

libzmq has no call to close one connection of a ROUTER, and closing its descriptor from
Python would pull it from under libzmq's I/O thread (which may then use or close a
number reused meanwhile). What it does offer: the monitor's ``ACCEPTED`` and
``DISCONNECTED`` events carry the connection's descriptor, and a message's ``SRCFD`` the
one it came over. A connection is closed by :func:`shut`: ``shutdown()`` on a duplicate
of the descriptor, after checking the duplicate is still the socket accepted. libzmq
reads end-of-file, drops the connection and closes its own descriptor, as when a peer
hangs up (``DISCONNECTED`` follows). A socket's identity is its inode (unique among live
sockets, not reused for a long while), so a number reused by another connection or file
is never shut.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
from collections.abc import Hashable

import zmq

from btcap.transports.base import TransportStats
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.newcomers import LINKS_PER_PEER, Close, Newcomers

__all__ = [
    "NO_HELLO",
    "STALL_S",
    "TOO_MANY_LINKS",
    "NewcomerWatch",
    "local_address",
    "shut",
    "socket_key",
]

log = get_logger(__name__)

NO_HELLO = "no hello"
"""The drop reason of a connection closed for saying no hello in time (or beyond the cap)."""
TOO_MANY_LINKS = "too many links"
"""The drop reason of a peer's oldest connection closed for a newer one beyond its share."""


def local_address(bound: str) -> object:
    """What ``getsockname()`` of a connection accepted on endpoint ``bound`` says: the
    port for tcp, the path for ipc (None for inproc, which has no descriptors)."""
    if bound.startswith("tcp://"):
        return int(bound.rsplit(":", 1)[1])
    if bound.startswith("ipc://@"):
        return b"\0" + bound.removeprefix("ipc://@").encode()
    if bound.startswith("ipc://"):
        return bound.removeprefix("ipc://")
    return None


def socket_key(fd: int, local: object) -> Hashable | None:
    """The identity of the connection on ``fd`` if it is one accepted on ``local`` (see
    :func:`local_address`), else None (closed meanwhile, or the number reused)."""
    sock = _duplicate(fd)
    if sock is None:
        return None
    try:
        with sock:
            if sock.getsockopt(socket.SOL_SOCKET, socket.SO_ACCEPTCONN):
                return None  # a listener, not a connection
            name = sock.getsockname()
            here = name[1] if sock.family in (socket.AF_INET, socket.AF_INET6) else name
            if isinstance(here, str) and isinstance(local, bytes):
                here = here.encode()
            if here != local:
                return None
            st = os.fstat(sock.fileno())
            return (st.st_dev, st.st_ino)
    except OSError:
        return None


def shut(fd: int, key: Hashable) -> bool:
    """Shut down the connection on ``fd`` if it is still the socket ``key`` names; libzmq
    then closes it as one its peer hung up. Whether it was shut."""
    sock = _duplicate(fd)
    if sock is None:
        return False
    try:
        with sock:
            st = os.fstat(sock.fileno())
            if (st.st_dev, st.st_ino) != key:
                return False
            sock.shutdown(socket.SHUT_RDWR)
            return True
    except OSError:
        return False


def _duplicate(fd: int) -> socket.socket | None:
    """A socket on a duplicate of ``fd`` (the caller closes it), None if ``fd`` is closed
    or no socket now (libzmq reuses numbers for its own descriptors too)."""
    try:
        dup = os.dup(fd)
    except OSError:
        return None
    try:
        return socket.socket(fileno=dup)
    except OSError:
        os.close(dup)
        return None


#: A timer this late means the loop was held up (a callback may take ~50 ms; a loaded
#: machine adds some), not that a newcomer stayed silent; then every wait pauses for the
#: delay, and this long more, for the loop to read what came meanwhile.
STALL_S = 0.25


class NewcomerWatch:
    """Feeds a ROUTER's connection events and admitted hellos to :class:`Newcomers` and
    shuts what it says to, on the running loop's time."""

    def __init__(
        self,
        bound: str,
        stats: TransportStats,
        system: str,
        deadline: float,
        cap: int,
        links: int = LINKS_PER_PEER,
    ) -> None:
        self.book = Newcomers(deadline, cap, links)
        self.local = local_address(bound)
        self.stats = stats
        self.system = system
        self._timer: asyncio.TimerHandle | None = None
        self._due = 0.0  # when the timer was meant to fire
        self._closed = False

    def accepted(self, fd: int) -> None:
        key = socket_key(fd, self.local)
        if key is None or self._closed:
            return  # gone already (its DISCONNECTED follows), or not ours
        loop = asyncio.get_running_loop()
        self._shut(self.book.accepted(fd, key, loop.time()), NO_HELLO)
        self._arm(loop)

    def gone(self, fd: int) -> None:
        self.book.gone(fd)

    def spoke(self, frame: object, peer: str) -> None:
        """A hello (or a message dialling a forgotten peer back) was admitted as ``peer``
        from the connection ``frame`` came over."""
        if self._closed or not isinstance(frame, zmq.Frame):
            return
        with contextlib.suppress(zmq.ZMQError, ValueError, TypeError):
            fd = int(frame.get(zmq.SRCFD))
            if fd < 0 or self.book.peer_of(fd) == peer:
                return
            key = self.book.waiting[fd][1] if fd in self.book.waiting else None
            key = key if key is not None else socket_key(fd, self.local)
            if key is not None:
                self._shut(self.book.spoke(fd, peer, key), TOO_MANY_LINKS)

    def dropped(self, peer: str) -> None:
        """``peer`` is no longer a peer: its connections must say hello again, in time."""
        if self._closed or not self.book.linked(peer):
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # not from the loop (links exist only while it runs): no clock
            return
        self._shut(self.book.dropped(peer, loop.time()), NO_HELLO)
        self._arm(loop)

    def close(self) -> None:
        self._closed = True
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _arm(self, loop: asyncio.AbstractEventLoop) -> None:
        due = self.book.next_due()
        if due is not None and self._timer is None:
            self._due = due
            self._timer = loop.call_at(due, self._expire)

    def _expire(self) -> None:
        self._timer = None
        if self._closed:
            return
        loop = asyncio.get_running_loop()
        late = loop.time() - self._due
        if late > STALL_S:  # the loop was held up: hellos sent meanwhile are still unread,
            self.book.stalled(late + STALL_S)  # so the wait pauses, and they get read first
        self._shut(self.book.due(loop.time()), NO_HELLO)
        self._arm(loop)

    def _shut(self, close: Close, reason: str) -> None:
        for fd, key in close:
            if not shut(fd, key):
                continue  # closed meanwhile: nothing held
            self.stats.drop(reason)
            n = self.stats.by_reason[reason]
            if worth_logging(n):
                log.warning(
                    "transport.connection_closed",
                    system=self.system,
                    reason=reason,
                    detail=self._why(reason),
                    count=n,
                )

    def _why(self, reason: str) -> str:
        if reason == TOO_MANY_LINKS:
            return "a peer's oldest inbound connection, for a newer one beyond its share"
        book = self.book
        return (
            f"an inbound connection said no hello within {book.deadline:g} s (or more than "
            f"{book.cap} waited): closed; raise hello_timeout_s/max_newcomers if honest "
            "peers are that slow"
        )
