"""One live process per name, and what each peer's role lets it send, for
:mod:`btcap.transports.zeromq`.

**Names.** Every transport says hello with its endpoint and a random *instance* token
(``H`` + endpoint + ``\\n`` + token). A hello for a peer we know, from another endpoint
and another instance, is either that peer restarted elsewhere (our link to the old one
has dropped: we follow it) or a second process under a live peer's name (our link to the
old one is up: refused). The newcomer is told why in a ``R`` frame sent to the endpoint
it announced (``NAME is already live at ENDPOINT (since ...)``) and its transport stops
with :class:`NameTaken`; with keys, what it sends on that connection is dropped.

**Roles.** A table (role -> the message types it may send, None: any) is given by the
layer that defines the protocol (:func:`btcap.team.membership.roles.role_table`); the transport
checks every tell and ask against the sender's role before delivering it.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Mapping
from typing import Any

import zmq

from btcap.errors import BtcapError
from btcap.transports.identity import OBSERVER, is_observer_id
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.message import Message
from btcap.transports.security import Curve

__all__ = [
    "TELL_S",
    "Claims",
    "NameTaken",
    "RoleTable",
    "hello_payload",
    "limits_for",
    "split_hello",
]

log = get_logger(__name__)

RoleTable = Mapping[str, frozenset[type[Message]] | None]
"""Role -> the message types a peer with that role may tell or ask (None: any)."""

_INSTANCE_MAX = 64
_REMEMBER = 256  #: refused connections and logged newcomers remembered (bounded)
TELL_S = 3.0  #: how long the socket telling a newcomer why stays open
MAX_TELLING = 8
"""Newcomers told why at once, at most: each costs a socket and a descriptor for
:data:`TELL_S`, and any local process can claim a live name from endless endpoints."""


class NameTaken(BtcapError, RuntimeError):
    """A teammate refused us: another live process already runs under our name."""


def hello_payload(endpoint: str, instance: str) -> bytes:
    return f"{endpoint}\n{instance}".encode()


def split_hello(payload: bytes) -> tuple[bytes, str]:
    """A hello's endpoint (still to be checked) and instance ("" from an older peer)."""
    endpoint, _, instance = payload.partition(b"\n")
    return endpoint, instance[:_INSTANCE_MAX].decode(errors="replace")


def limits_for(
    peer: str, role: str | None, table: RoleTable | None
) -> frozenset[type[Message]] | None:
    """What ``peer`` may send (None: anything). Without keys ``role`` is None: only an
    id that declares an observer (``NAME+TAG``) is limited."""
    if table is None:
        return None
    if role is None and is_observer_id(peer):
        role = OBSERVER
    if role is None:
        return None
    return table.get(role, frozenset())


class Claims:
    """Instances of peers, refused connections and the newcomers told so."""

    def __init__(self, system: str) -> None:
        self.system = system
        self.instance = secrets.token_hex(8)  #: ours, sent in every hello
        self.instances: dict[str, str] = {}  #: peer -> the instance its hello named
        self.refused_links: dict[bytes, None] = {}  #: keyed routing ids refused
        self.refused = 0  #: second processes refused
        self.newcomers = 0  #: the (name, endpoint)s they came from, logged at a falling rate
        self._told: dict[tuple[str, str], None] = {}
        self._tellers: dict[zmq.Socket[bytes], tuple[str, str]] = {}  #: -> who it tells

    def seen(self, peer: str, instance: str) -> None:
        """``peer`` (a peer we keep: only those, so made-up names leave nothing behind)
        runs as ``instance``."""
        if instance:
            self.instances[peer] = instance

    def forget(self, peer: str) -> None:
        """``peer`` is no longer a peer of ours."""
        self.instances.pop(peer, None)

    def is_second(self, peer: str, instance: str) -> bool:
        """Whether a hello under ``peer``'s name (from another endpoint, while our link to
        the known one is up) names another instance than the known one's."""
        known = self.instances.get(peer)
        return bool(instance) and known is not None and known != instance

    def refuse(
        self,
        ctx: zmq.Context[Any],
        curve: Curve | None,
        own_id: bytes,
        peer: str,
        endpoint: str,
        live_at: str,
        up_since: float,
        raw_ident: bytes | None,
    ) -> zmq.Socket[bytes] | None:
        """Refuse a second process: remember its connection, log once, tell it why (the
        socket telling it, for the caller to close after :data:`TELL_S`)."""
        self.refused += 1
        if raw_ident is not None:
            self._remember(self.refused_links, raw_ident)
        since = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(up_since))
        why = f"{peer} is already live at {live_at} (since {since}); stop it or use another name"
        new = (peer, endpoint) not in self._told
        if new:
            self._remember(self._told, (peer, endpoint))
            self.newcomers += 1
        if new and worth_logging(self.newcomers):  # endless endpoints, not endless lines
            log.warning(
                "transport.name_taken",
                system=self.system,
                peer=peer,
                newcomer=endpoint,
                live_at=live_at,
                detail="a second process under a live member's name: refused",
                count=self.newcomers,
            )
        if len(self._tellers) >= MAX_TELLING or (peer, endpoint) in self._tellers.values():
            return None  # refused all the same; told once the ones being told are
        return self._tell(ctx, curve, own_id, peer, endpoint, why)

    def _tell(
        self,
        ctx: zmq.Context[Any],
        curve: Curve | None,
        own_id: bytes,
        peer: str,
        endpoint: str,
        why: str,
    ) -> zmq.Socket[bytes] | None:
        sock: zmq.Socket[bytes] = ctx.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        # A routing id of its own, as every link has (see zmq_sockets.open_dealer).
        sock.setsockopt(zmq.ROUTING_ID, own_id + b"/" + secrets.token_hex(6).encode())
        try:
            if curve is not None:
                curve.client(sock, peer)
            sock.connect(endpoint)
            sock.send(b"R" + why.encode()[:1000], zmq.NOBLOCK)
        except (zmq.ZMQError, ValueError) as exc:
            log.info("transport.name_taken_untold", system=self.system, peer=peer, error=str(exc))
            sock.close(0)
            return None
        self._tellers[sock] = (peer, endpoint)
        return sock

    def done_telling(self, sock: zmq.Socket[bytes] | None = None) -> None:
        """Close a socket that told a newcomer why (None: all of them, on close)."""
        for s in [sock] if sock is not None else list(self._tellers):
            if s in self._tellers:
                del self._tellers[s]
                s.close(0)

    def blocked(self, raw_ident: bytes) -> bool:
        return raw_ident in self.refused_links

    @staticmethod
    def _remember(table: dict[Any, None], key: Any) -> None:
        table[key] = None
        while len(table) > _REMEMBER:
            del table[next(iter(table))]
