"""Which inbound connections of a ZeroMQ transport to close, decided on explicit time
(sans-IO: no zmq, no asyncio; :mod:`~btcap.transports.zmq_newcomers` acts on it).

Every connection a ROUTER accepts holds a file descriptor until the peer closes it, and
libzmq closes none for silence: a process that completes the handshake (any local one
without keys, a key holder with them) and never speaks could hold descriptors without
end. Every btcap peer says hello first on each connection, so a connection earns its
descriptor by a hello the transport admitted:

- a *newcomer* (accepted, no admitted hello yet) is closed ``deadline`` seconds after it
  was accepted; at most ``cap`` wait at once, the oldest making room;
- a *link* (its hello admitted) is kept while its peer is; at most ``links``
  (:data:`LINKS_PER_PEER` by default) per peer, the oldest making room (a relinking
  peer has two for a moment; a name claimed over and over has no more);
- a link whose peer the transport dropped is a newcomer again: it is closed unless it
  says hello (or is dialled back) within ``deadline``;
- time the caller could not read in (a stalled event loop) does not count: a hello sent
  then waits unread, and an honest newcomer must not be closed for the caller's delay.

Connections are named by their descriptor (what libzmq's events carry) with a ``key``
naming the socket itself, for the caller to check that a descriptor still holds the
same socket before closing it.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Hashable

__all__ = ["LINKS_PER_PEER", "Close", "Newcomers"]

LINKS_PER_PEER = 4
"""Inbound connections kept per peer: its link, one while it relinks, and spare."""

Close = list[tuple[int, Hashable]]
"""Connections to close: ``(descriptor, key)`` each."""


class Newcomers:
    """Inbound connections without an admitted hello, and the peers of those with one."""

    def __init__(self, deadline: float, cap: int, links: int = LINKS_PER_PEER) -> None:
        if deadline <= 0 or cap < 1 or links < 1:
            what = f"hello deadline {deadline} s, cap {cap} and links {links}"
            raise ValueError(f"{what}: all must be > 0")
        self.deadline = deadline
        self.cap = cap
        self.links_per_peer = links
        #: Newcomers, oldest first: descriptor -> (since when, key).
        self.waiting: OrderedDict[int, tuple[float, Hashable]] = OrderedDict()
        #: Links: descriptor -> (peer, key); and each peer's, oldest first.
        self.links: dict[int, tuple[str, Hashable]] = {}
        self._of: dict[str, OrderedDict[int, None]] = {}
        self.closed = 0  #: connections this book had closed

    def accepted(self, fd: int, key: Hashable, now: float) -> Close:
        """A connection was accepted on descriptor ``fd``; the newcomers over the cap."""
        if fd in self.links:  # its hello was read before the event: a link already
            return []
        self.waiting.pop(fd, None)
        self.waiting[fd] = (now, key)
        return self._over_cap()

    def gone(self, fd: int) -> None:
        """The connection on ``fd`` was closed (by its peer, libzmq or us)."""
        self.waiting.pop(fd, None)
        link = self.links.pop(fd, None)
        if link is not None:
            peer_links = self._of[link[0]]
            peer_links.pop(fd, None)
            if not peer_links:
                del self._of[link[0]]

    def spoke(self, fd: int, peer: str, key: Hashable) -> Close:
        """The connection on ``fd`` said a hello admitted as ``peer`` (``key``: its
        socket's, used if no accept was seen); the links of ``peer`` over its share."""
        waited = self.waiting.pop(fd, None)
        old = self.links.get(fd)
        if old is not None and old[0] == peer:
            return []
        self.gone(fd)
        self.links[fd] = (peer, key if waited is None else waited[1])
        peer_links = self._of.setdefault(peer, OrderedDict())
        peer_links[fd] = None
        close: Close = []
        while len(peer_links) > self.links_per_peer:
            oldest = next(iter(peer_links))
            close.append((oldest, self.links[oldest][1]))
            self.gone(oldest)
        self.closed += len(close)
        return close

    def peer_of(self, fd: int) -> str | None:
        """The peer whose link ``fd`` is, None for a newcomer or a stranger to us."""
        link = self.links.get(fd)
        return None if link is None else link[0]

    def linked(self, peer: str) -> bool:
        """Whether ``peer`` has a link."""
        return peer in self._of

    def dropped(self, peer: str, now: float) -> Close:
        """The transport dropped ``peer``: its links are newcomers again, from ``now``."""
        for fd in list(self._of.get(peer, ())):
            key = self.links[fd][1]
            self.gone(fd)
            self.waiting[fd] = (now, key)
        return self._over_cap()

    def due(self, now: float) -> Close:
        """The newcomers whose deadline has passed at ``now`` (forgotten: close them)."""
        close: Close = []
        while self.waiting:
            fd, (since, key) = next(iter(self.waiting.items()))
            if now - since < self.deadline:
                break
            del self.waiting[fd]
            close.append((fd, key))
        self.closed += len(close)
        return close

    def stalled(self, seconds: float) -> None:
        """Nothing was read for ``seconds`` (the caller's loop was held up): no newcomer's
        wait counts them, since a hello that came meanwhile is not read yet."""
        if seconds > 0:
            for fd, (since, key) in self.waiting.items():
                self.waiting[fd] = (since + seconds, key)

    def next_due(self) -> float | None:
        """When the oldest newcomer's deadline passes, None if none waits."""
        if not self.waiting:
            return None
        return next(iter(self.waiting.values()))[0] + self.deadline

    def _over_cap(self) -> Close:
        close: Close = []
        while len(self.waiting) > self.cap:
            fd, (_since, key) = self.waiting.popitem(last=False)
            close.append((fd, key))
        self.closed += len(close)
        return close
