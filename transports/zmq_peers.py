"""Which peers a ZeroMQ transport keeps dialling: :class:`PeerBook` decides (sans-IO, on
the loop's time), :class:`PeerFates` acts (a part of
:class:`~btcap.transports.zeromq.ZmqTransport`).

Each peer dialled costs a DEALER and a monitor: three descriptors and, while nobody
answers, a re-dial every 100 ms. Anybody may say hello under any number of made-up
names, and hearsay names more, so a peer earns its sockets by speaking:

- a *stranger* (known only from its hello, an introduction, or again since its link
  dropped) is forgotten after ``ttl`` seconds unless it speaks; at most
  ``max_strangers`` are kept, the oldest making room;
- a stranger that never spoke and where nobody answers for ``UNREACHABLE_TRIES`` dials
  is dropped at once;
- a peer the layer above declared gone (failed, left), or one that had spoken and fell
  silent as a stranger again, is *forgotten*: its endpoint is remembered (at most
  ``max_forgotten``), so if it speaks again (a false failure) it is dialled back.
"""

from __future__ import annotations

import asyncio
import enum
from collections import OrderedDict
from typing import TYPE_CHECKING, Any

from btcap._enum import FastEnumType
from btcap.transports.base import TransportStats
from btcap.transports.log import get_logger
from btcap.transports.zmq_claims import Claims
from btcap.transports.zmq_endpoints import SCHEMES, check_id
from btcap.transports.zmq_monitors import Monitor, RouterEvents
from btcap.transports.zmq_sockets import reject

__all__ = ["UNREACHABLE_TRIES", "Fate", "PeerBook", "PeerFates"]

log = get_logger(__name__)

UNREACHABLE_TRIES = 3
"""Failed dials after which a stranger that never spoke is dropped."""
_BATCH = 256
"""Monitor events read per callback before other callbacks get a turn."""


class Fate(enum.Enum, metaclass=FastEnumType):
    """What to do with a peer, as :class:`PeerBook` decides."""

    KEEP = "keep"
    WATCH = "watch"  #: a stranger from now: drop it after ``ttl`` unless it speaks
    DROP = "drop"  #: close its sockets and forget it entirely
    FORGET = "forget"  #: close its sockets; dial it back if it speaks


class PeerBook:
    """Strangers, who of them spoke before, failed dials and forgotten endpoints."""

    def __init__(self, ttl: float, max_strangers: int, max_forgotten: int) -> None:
        self.ttl = ttl
        self.max_strangers = max_strangers
        self.max_forgotten = max_forgotten
        #: Strangers and when they became one (read on the receive path: keep it a dict).
        self.since: dict[str, float] = {}
        self._spoke: set[str] = set()
        self._tries: dict[str, int] = {}
        self._forgotten: OrderedDict[str, str] = OrderedDict()

    def met(self, peer: str, now: float) -> None:
        self.since[peer] = now

    def vouched(self, peer: str) -> None:
        """``peer`` spoke: no longer a stranger."""
        self.since.pop(peer, None)

    def full(self) -> bool:
        return len(self.since) >= self.max_strangers

    def oldest(self) -> str | None:
        return min(self.since, key=self.since.__getitem__) if self.since else None

    def dropped(self, peer: str) -> None:
        """``peer``'s sockets are gone: nothing is kept of it but a forgotten endpoint."""
        self.since.pop(peer, None)
        self._spoke.discard(peer)
        self._tries.pop(peer, None)

    def lapsed(self, peer: str) -> Fate:
        """``peer``'s link dropped: a stranger again (unless it is one already)."""
        if peer in self.since:
            return Fate.KEEP
        self._spoke.add(peer)
        return Fate.WATCH

    def unreachable(self, peer: str) -> Fate:
        """A dial of ``peer`` failed (nobody listens where it said)."""
        if peer not in self.since:
            return self.lapsed(peer)
        if peer in self._spoke:
            return Fate.KEEP  # it spoke: its time as a stranger decides
        tries = self._tries[peer] = self._tries.get(peer, 0) + 1
        return Fate.DROP if tries >= UNREACHABLE_TRIES else Fate.KEEP

    def expired(self, peer: str, met: float) -> Fate:
        """``ttl`` passed since ``peer`` became a stranger at ``met``."""
        if self.since.get(peer) != met:
            return Fate.KEEP  # it spoke meanwhile, or was dropped
        return Fate.FORGET if peer in self._spoke else Fate.DROP

    def remember(self, peer: str, endpoint: str) -> None:
        """``peer`` was forgotten: where to dial it back if it speaks again."""
        self._forgotten[peer] = endpoint
        self._forgotten.move_to_end(peer)
        while len(self._forgotten) > self.max_forgotten:
            self._forgotten.popitem(last=False)

    def recall(self, peer: str) -> str | None:
        """The endpoint of a forgotten ``peer`` that speaks again (taken), or None."""
        return self._forgotten.pop(peer, None) if self._forgotten else None


class PeerFates:
    """What :class:`~btcap.transports.zeromq.ZmqTransport` does with its peers' fates:
    forgetting the gone, watching strangers, dialling back who speaks again."""

    system_id: str
    stats: TransportStats
    accept_hello: bool
    max_peers: int
    _dealers: dict[str, Any]
    _strangers: PeerBook
    _endpoints: dict[str, str]
    _configured: set[str]
    _monitors: dict[str, Monitor]
    _claims: Claims
    _events: RouterEvents
    _loop: asyncio.AbstractEventLoop | None
    _closed: bool

    if TYPE_CHECKING:

        def remove_peer(self, system_id: str) -> None: ...

        def _unlink(self, system_id: str) -> None: ...

        def _connect(self, system_id: str, endpoint: str) -> None: ...

        def _second(self, peer: str, endpoint: str, known: str | None, instance: str) -> bool: ...

        def _malformed(self, reason: str, ident: bytes, detail: str) -> bool: ...

    def _watch(self, monitor: Monitor) -> None:
        """Read ``monitor``'s events (what happens to our link to its peer) from now on."""
        assert self._loop is not None
        self._loop.add_reader(monitor.fd, self._on_monitor, monitor)
        # Events that came before we watched have already reset the descriptor.
        self._loop.call_soon(self._on_monitor, monitor)

    def _on_monitor(self, monitor: Monitor) -> None:
        if monitor.drain(_BATCH, self._relink, self._unreachable) and self._loop is not None:
            self._loop.call_soon(self._on_monitor, monitor)

    def _relink(self, monitor: Monitor) -> None:
        # A fresh DEALER, its hello first (see zmq_sockets: why not the dropped one).
        peer = monitor.peer
        if self._monitors.get(peer) is monitor and not self._closed:
            log.info("transport.peer_relinked", system=self.system_id, peer=peer)
            self._connect(peer, self._endpoints.pop(peer))
            if peer not in self._configured:  # gone for good unless it speaks again
                self._fate(peer, self._strangers.lapsed(peer))

    def forget(self, system_id: str) -> None:
        """A peer has gone (declared failed, or left): stop dialling it, close its sockets
        and drop what is queued for it. A configured peer is dialled afresh (it may come
        back without knowing us); any other is dialled back only if it speaks again."""
        endpoint = self._endpoints.get(system_id)
        if endpoint is None or self._closed:
            return
        if system_id in self._configured:
            self._unlink(system_id)  # what was queued goes with the old DEALER
            self._connect(system_id, endpoint)
            return
        self.remove_peer(system_id)
        self._strangers.remember(system_id, endpoint)
        log.info("transport.peer_forgotten", system=self.system_id, peer=system_id)

    def unreachable(self) -> frozenset[str]:
        """Peers whose last dials all failed (see :data:`UNREACHABLE_TRIES`)."""
        return frozenset(p for p, m in self._monitors.items() if m.retries >= UNREACHABLE_TRIES)

    def _unreachable(self, monitor: Monitor) -> None:
        peer = monitor.peer  # nobody listens where it said
        if self._monitors.get(peer) is monitor and peer not in self._configured:
            self._fate(peer, self._strangers.unreachable(peer))

    def _fate(self, peer: str, fate: Fate) -> None:
        if self._closed or fate is Fate.KEEP:
            return
        if fate is Fate.WATCH:
            self._stranger(peer)
        elif fate is Fate.FORGET:
            self.forget(peer)
        else:
            self.remove_peer(peer)

    def _recall(self, ident: bytes, frame: object) -> str | None:
        """A forgotten peer speaks again (it was declared failed, falsely): dial it back;
        the connection ``frame`` came over is its link again."""
        peer = ident.decode(errors="replace")
        endpoint = self._strangers.recall(peer)
        if endpoint is None or not self._admit(peer, endpoint, True):
            return None
        self._strangers.vouched(peer)
        if self._events.watch is not None:
            self._events.watch.spoke(frame, peer)
        return peer

    def introduce(self, system_id: str, endpoint: str) -> bool:
        """Dial a teammate others told us of, as a stranger until it speaks (see class)."""
        if check_id(system_id) is not None or not endpoint.startswith(SCHEMES):
            return False
        if system_id in self._endpoints:
            return False
        if self._strangers.full():
            # Hearsay is not dialled in bulk: the others wait until these have spoken.
            self.stats.drop("too many strangers")
            return False
        return self._admit(system_id, endpoint, True)

    def _stranger(self, peer: str) -> None:
        """``peer`` is dropped after ``stranger_ttl_s`` unless it speaks meanwhile."""
        if self._loop is not None:
            now = self._loop.time()
            self._strangers.met(peer, now)
            self._loop.call_later(self._strangers.ttl, self._forget, peer, now)

    def _forget(self, peer: str, met: float) -> None:
        self._fate(peer, self._strangers.expired(peer, met))

    def _admit(self, peer: str, endpoint: str, accept: bool, instance: str = "") -> bool:
        """Connect to a peer that announced itself (False: refused, counted and logged).
        Peers cost sockets: made-up ids must neither exhaust them nor keep a newcomer out."""
        ident = peer.encode()
        known = self._endpoints.get(peer)
        if self._second(peer, endpoint, known, instance):
            return False
        if known == endpoint or peer in self._configured:
            return True
        if known is None and not accept:
            self.stats.unknown_peer += 1
            reject(self.stats, self.system_id, "unknown peer", ident, "hello refused")
            return False
        if known is None and self._strangers.full():
            self.remove_peer(self._strangers.oldest() or peer)  # the oldest makes room
        if known is None and len(self._dealers) >= self.max_peers:
            stranger = self._strangers.oldest()  # the longest silent one makes room
            if stranger is None:
                self.stats.unknown_peer += 1
                why = f"already {len(self._dealers)}"
                reject(self.stats, self.system_id, "too many peers", ident, why)
                return False
            self.remove_peer(stranger)
        try:
            self._connect(peer, endpoint)
        except (ValueError, RuntimeError) as exc:
            self._malformed("bad hello", ident, str(exc)[:200])
            return False
        if known is None:
            self._claims.seen(peer, instance)  # only now: refused names leave nothing
            self._stranger(peer)
        event = "transport.peer_joined" if known is None else "transport.peer_moved"
        log.info(event, system=self.system_id, peer=peer, endpoint=endpoint)
        return True
