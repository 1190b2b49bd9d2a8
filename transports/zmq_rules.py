"""Who a peer of :class:`~btcap.transports.zeromq.ZmqTransport` is: where it listens, its
role and what that lets it send, whether it is an observer, and whether its name is
already live elsewhere (see :mod:`~btcap.transports.zmq_claims`). A mixin: the
transport calls these hooks from its receive path; the state they keep is theirs."""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import time
from collections.abc import Callable
from typing import Any

import msgspec
import zmq

from btcap.transports.base import BROADCAST, TransportStats
from btcap.transports.bounds import check_nesting, message_tag, split_envelope
from btcap.transports.codec import Codec
from btcap.transports.identity import OBSERVER, is_observer_id, member_of
from btcap.transports.log import get_logger
from btcap.transports.security import Curve, TeamKeys
from btcap.transports.zmq_claims import (
    TELL_S,
    Claims,
    NameTaken,
    RoleTable,
    hello_payload,
    limits_for,
    split_hello,
)
from btcap.transports.zmq_endpoints import parse_hello
from btcap.transports.zmq_monitors import Monitor, RouterEvents
from btcap.transports.zmq_peers import PeerBook
from btcap.transports.zmq_sockets import reject

__all__ = ["HEAVY_BYTES", "NON_MEMBER_BYTES", "REFUSAL", "PeerRules", "split_hello"]

log = get_logger(__name__)

HELLO_BYTE = b"H"[0]
"""The first byte of a hello frame."""
REFUSAL = b"R"[0]
"""The first byte of a frame telling a newcomer why its name was refused."""
NON_MEMBER_BYTES = 256 * 1024
"""Largest message a peer that is no member may send (a roster of 1,024 fits)."""
_BATCH = 256
_REFUSED = "not allowed for its role"
HEAVY_BYTES = 256 * 1024
"""A frame this big is screened before msgspec sees it, and costs its receiver's turn."""
_TOO_BIG = "too big for a non-member"
_NO_INSTANCE = "hello without an instance token"
_ANSWER_S = 10.0
"""A refusal counts only this soon after our link to the refusing peer came up."""


class PeerRules:
    """Roles, observers and one live process per name, for a ZeroMQ transport."""

    # The transport's own state these hooks read (set by its __init__).
    system_id: str
    endpoint: str
    curve: Curve | None
    stats: TransportStats
    codec: Codec
    _ctx: zmq.Context[zmq.Socket[bytes]]
    _id: bytes
    _known: dict[bytes, str]
    _dealers: dict[str, zmq.Socket[bytes]]
    _endpoints: dict[str, str]
    _monitors: dict[str, Monitor]
    _strangers: PeerBook
    _events: RouterEvents
    _loop: asyncio.AbstractEventLoop | None
    _stopped: asyncio.Future[None] | None
    accept_hello: bool
    hellos: int

    def _init_rules(self) -> None:
        self._claims = Claims(self.system_id)
        self._roles: RoleTable | None = None
        self._limited: dict[str, frozenset[type[Any]]] = {}  # peers with limits only
        self._observers: set[str] = set()
        self._observed: dict[str, float] = {}
        self._raw_ident = b""
        self._members: Callable[[str], bool] | None = None
        #: Largest message a non-member may send (see :meth:`members`).
        self.max_non_member_bytes = NON_MEMBER_BYTES
        self._revoked: set[bytes] = set()  #: members whose key left the trusted folder
        #: Why a teammate refused us (another live process has our name), or None.
        self.name_taken: str | None = None

    def _relink(self, monitor: Monitor) -> None:
        raise NotImplementedError  # the transport's

    def _malformed(self, reason: str, ident: bytes, detail: str) -> bool:
        raise NotImplementedError  # the transport's

    def _forget(self, peer: str, met: float) -> None:
        raise NotImplementedError  # the transport's

    def _admit(self, peer: str, endpoint: str, accept: bool, instance: str = "") -> bool:
        raise NotImplementedError  # the transport's (PeerFates)

    def remove_peer(self, system_id: str) -> None:
        raise NotImplementedError  # the transport's

    # -- where peers are --------------------------------------------------------------
    def __repr__(self) -> str:
        return f"ZmqTransport({self.system_id!r}, {self.endpoint!r}, peers={len(self._dealers)})"

    def peers(self) -> frozenset[str]:
        return frozenset(self._dealers)

    def peer_endpoints(self) -> dict[str, str]:
        return dict(self._endpoints)

    def routing_id(self, peer: str) -> bytes:
        """What our link to ``peer`` is called there: our id, a ``/`` and a suffix."""
        return bytes(self._dealers[peer].getsockopt(zmq.ROUTING_ID))

    def endpoint_of(self, system_id: str) -> str | None:
        return self.endpoint if system_id == self.system_id else self._endpoints.get(system_id)

    # -- roles ------------------------------------------------------------------------
    def limit(self, table: RoleTable | None) -> None:
        """What each role may send (role -> message types, None: any), checked on every
        tell and ask received; None: no limits."""
        self._roles = table
        for peer in self._known.values():
            self._classify(peer)

    def role_of(self, peer: str) -> str | None:
        """A peer's role: its key's (an observer id's: ``observer``); without keys
        ``observer`` for an observer id, None (anything) for the others."""
        if self.curve is not None:
            return self.curve.team.role_of(peer)
        return OBSERVER if is_observer_id(peer) else None

    def _classify(self, peer: str) -> None:
        role = self.role_of(peer)
        allowed = limits_for(peer, role, self._roles)
        if allowed is None:
            self._limited.pop(peer, None)
        else:
            self._limited[peer] = allowed
        if role == OBSERVER or is_observer_id(peer):
            self._observers.add(peer)  # it asks: broadcasts (team news) skip it
        else:
            self._observers.discard(peer)

    def _unclassify(self, peer: str) -> None:
        self._limited.pop(peer, None)
        self._observers.discard(peer)
        self._observed.pop(peer, None)

    def members(self, check: Callable[[str], bool] | None) -> None:
        """Who is a member (``check(peer)``, asked only of a big message): a peer that is
        none, and an observer, may send messages of at most :attr:`max_non_member_bytes`;
        None: everyone may send up to the frame limit."""
        self._members = check

    def _non_member(self, peer: str) -> bool:
        check = self._members
        return peer in self._observers or (check is not None and not check(peer))

    def _prescreen(self, peer: str, ident: bytes, data: memoryview) -> bool | None:
        """A big frame's checks, its envelope read in Python (msgspec would walk its
        message to reach the end of the envelope): True if refused, None if its envelope
        is not in btcap's form (the decoder then checks it)."""
        split = split_envelope(data)
        if split is None:
            return None
        kind, sender, to, start = split
        if sender != peer:
            return self._malformed("sender mismatch", ident, f"claims {sender[:64]!r}")
        if to != self.system_id and to != BROADCAST:
            return self._malformed("wrong recipient", ident, f"for {to[:64]!r}")
        limited = peer in self._limited
        return self._refused(peer, ident, kind, data[start:], limited)

    def _refused(
        self, peer: str, ident: bytes, kind: int, raw: msgspec.Raw | memoryview, limited: bool
    ) -> bool:
        """Whether a message is refused before it is decoded: one its sender's role may
        not send (read from its tag), too big for a non-member, or nesting too much."""
        if limited and self._refused_type(peer, kind, raw):
            return True
        size = len(raw)
        if size > self.max_non_member_bytes and self._non_member(peer):
            what = f"{size} bytes, at most {self.max_non_member_bytes} from a non-member"
            reject(self.stats, self.system_id, _TOO_BIG, ident, what)
            return True
        if (why := check_nesting(raw)) is not None:
            return self._malformed("nested too much", ident, why)
        return False

    def _refused_type(self, peer: str, kind: int, raw: msgspec.Raw | memoryview) -> bool:
        """Whether a limited peer's tell or ask is of a type its role may not send."""
        if kind >= 2:  # replies reach only who asked
            return False
        tag = message_tag(raw)
        if self.codec.message_type(tag) in self._limited[peer]:
            return False
        self.stats.received += 1
        role = self.role_of(peer) or OBSERVER
        name = "nil" if tag is None else tag[:64].decode(errors="replace")
        reject(self.stats, self.system_id, _REFUSED, peer.encode(), f"{role} may not send {name}")
        return True

    def _observing(self, peer: str) -> None:
        """An observer stays a stranger, forgotten once it falls silent."""
        if peer in self._observers and self._loop is not None:
            now, met = self._loop.time(), self._observed.get(peer)
            if met is None or now - met > self._strangers.ttl / 8:
                self._observed[peer] = now
                self._strangers.met(peer, now)
                self._loop.call_later(self._strangers.ttl, self._forget, peer, now)
            else:
                self._strangers.since[peer] = met  # what the pending _forget looks for

    # -- names ------------------------------------------------------------------------
    def _hello(self) -> bytes:
        return hello_payload(self.endpoint, self._claims.instance)

    def _blocked(self, raw: bytes, member: bytes, part: zmq.Frame) -> bool:
        """With keys: whether a connection belongs to a refused second process, or was
        made with a key we no longer trust (then it is cut)."""
        self._raw_ident = raw
        if self._claims.refused_links and self._claims.blocked(raw):
            reject(self.stats, self.system_id, "name taken", member, "a refused second process")
            return True
        if self._revoked and member.partition(b"+")[0] in self._revoked:
            reject(self.stats, self.system_id, "key revoked", member, "key no longer trusted")
            _cut(part)
            return True
        return False

    # -- revocation -------------------------------------------------------------------
    def _trust(self, team: TeamKeys) -> None:
        """Admit the reloaded ``team`` (see :mod:`~btcap.transports.trust`): ZAP refuses
        a removed or replaced key from now on, our links to its member are closed and
        what comes over its links into us is dropped, each cut at its next message."""
        assert self.curve is not None
        old = set(self.curve.team)
        revoked = self.curve.trust(team)
        self._revoked = {n.encode() for n in revoked} | {
            n for n in self._revoked if n.decode() not in team
        }
        for peer in set(self._dealers) | set(self._known.values()):
            if member_of(peer) in revoked:
                self.remove_peer(peer)
            else:
                self._classify(peer)  # its role may have changed
        added = sorted(set(team) - old)
        if revoked or added:
            log.warning(
                "transport.trusted_reloaded",
                system=self.system_id,
                revoked=sorted(revoked),
                added=added,
                detail=f"keys.trusted: {team.folder} changed: links of revoked keys closed",
            )

    def _second(self, peer: str, endpoint: str, known: str | None, instance: str) -> bool:
        """Whether a hello under a known peer's name from another endpoint comes from a
        second process (our link to the known one is up, the instance differs): refused,
        logged once and told why. Otherwise (a restart elsewhere) its instance is noted.
        A hello without an instance would move a known peer on nobody's word (every
        btcap peer sends one): ignored, counted and logged."""
        if not instance and known is not None and known != endpoint:
            what = f"it would move {peer} from {known} to {endpoint[:200]}: ignored"
            reject(self.stats, self.system_id, _NO_INSTANCE, peer.encode(), what)
            return True
        monitor = self._monitors.get(peer) if known not in (None, endpoint) else None
        if monitor is not None:
            monitor.drain(_BATCH, self._relink)  # a drop not yet read means a restart
            monitor = self._monitors.get(peer)
        up_since = None if monitor is None else monitor.up_since
        if up_since is None or known is None or not self._claims.is_second(peer, instance):
            if known is not None:  # a newcomer's is noted once it is admitted (_admit)
                self._claims.seen(peer, instance)
            return False
        raw = self._raw_ident if self.curve is not None else None
        self.stats.drop("name taken")
        sock = self._claims.refuse(
            self._ctx, self.curve, self._id, peer, endpoint, known, up_since, raw
        )
        if sock is not None and self._loop is not None:
            self._loop.call_later(TELL_S, self._claims.done_telling, sock)
        return True

    def _control(self, ident: bytes, kind: int, body: memoryview) -> bool:
        """A frame that is no message: a hello, a refusal, or junk (then True)."""
        malformed = self.stats.malformed  # what a hello or a refusal may find wrong
        if kind == HELLO_BYTE:
            where, instance = split_hello(bytes(body[1:]))
            try:
                peer, endpoint = parse_hello(ident, where, self.system_id)
            except ValueError as exc:
                return self._malformed("bad hello", ident, str(exc))
            if self._admit(peer, endpoint, self.accept_hello, instance):
                self.hellos += 1
                if self._events.watch is not None:
                    self._events.watch.spoke(body.obj, peer)  # this connection is peer's
        elif kind == REFUSAL:
            self._refused_by(ident, bytes(body[1:]))
        else:
            return self._malformed("unknown frame kind", ident, repr(bytes(body[:8])))
        return self.stats.malformed != malformed

    def _refused_by(self, ident: bytes, text: bytes) -> None:
        """A teammate says another live process has our name: stop serving."""
        peer = self._known.get(ident)
        if peer is None:
            self.stats.malformed += 1
            reject(self.stats, self.system_id, "bad refusal", ident, "not from a peer we dialled")
            return
        if self.name_taken is not None:
            return
        monitor = self._monitors.get(peer)
        if monitor is not None:  # a refusal answers our hello at once, or it is forged
            monitor.drain(_BATCH, self._relink)
            up = self._monitors[peer].up_since if peer in self._monitors else None
            if up is None or time.time() - up > _ANSWER_S:
                self.stats.malformed += 1
                reject(self.stats, self.system_id, "bad refusal", ident, "not an answer to a hello")
                return
        self.name_taken = f"{peer} refused us: {text[:1000].decode(errors='replace')}"
        log.error("transport.name_taken", system=self.system_id, detail=self.name_taken)
        if self._stopped is not None and not self._stopped.done():
            self._stopped.set_result(None)

    def _raise_if_refused(self) -> None:
        if self.name_taken is not None:
            raise NameTaken(self.name_taken)

    def _stop_rules(self) -> None:
        self._claims.done_telling()


def _cut(part: zmq.Frame) -> None:
    """Close the TCP connection ``part`` came over (libzmq then drops it and the peer's
    reconnection meets ZAP, which refuses the key): shut down on a duplicate of its
    descriptor, so libzmq's own is never closed under it."""
    with contextlib.suppress(zmq.ZMQError, OSError, ValueError):
        fd = int(part.get(zmq.SRCFD))
        if fd >= 0:
            with socket.socket(fileno=os.dup(fd)) as sock:
                sock.shutdown(socket.SHUT_RDWR)
