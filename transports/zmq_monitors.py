"""The connection monitors of :mod:`btcap.transports.zeromq`: what libzmq did to a link.

libzmq never turns a dropped link, a refused or failed handshake, or a frame over
``MAXMSGSIZE`` into a message: they show only as events on a monitor socket. A DEALER's
:class:`Monitor` tells the transport when to relink (see :mod:`~btcap.transports.zmq_sockets`
for why a dropped DEALER is replaced); the ROUTER's :class:`RouterEvents` counts what
inbound connections lost.
"""

from __future__ import annotations

import asyncio
import sys
import time
from collections.abc import Callable

import zmq
from zmq.utils.monitor import parse_monitor_message

from btcap.transports.base import TransportStats
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.refusals import FAILED, HANDSHAKE_EVENTS, REFUSED, SUCCEEDED, Refusals
from btcap.transports.security import Curve
from btcap.transports.zmq_io import EVENTS, NOBLOCK, POLLIN, fd_of
from btcap.transports.zmq_newcomers import NewcomerWatch

__all__ = ["ACCEPTED", "DISCONNECTED", "RETRIED", "Monitor", "RouterEvents"]

log = get_logger(__name__)

# Plain ints, as zmq_io's flags: pyzmq's enums cost an enum call on every use.
DISCONNECTED = int(zmq.EVENT_DISCONNECTED)
ACCEPTED = int(zmq.EVENT_ACCEPTED)
RETRIED = int(zmq.EVENT_CONNECT_RETRIED)


class Monitor:
    """Connection events of one DEALER, read from its zmq monitor socket.

    After a failed handshake the link is dialled again only after a pause that grows
    with each failure (:meth:`Refusals.failed`), and a success cancels it.
    """

    __slots__ = (
        "closed",
        "dealer",
        "endpoint",
        "failed",
        "fd",
        "peer",
        "redial",
        "refusals",
        "retries",
        "socket",
        "up_since",
    )

    def __init__(
        self,
        peer: str,
        dealer: zmq.Socket[bytes],
        socket: zmq.Socket[bytes],
        endpoint: str,
        refusals: Refusals,
    ) -> None:
        self.peer = peer
        self.dealer = dealer
        self.socket = socket
        self.endpoint = endpoint
        self.refusals = refusals
        self.fd = fd_of(socket)
        self.closed = False
        self.failed: float | None = None  #: the pause before re-dialling, once failed
        self.redial: asyncio.TimerHandle | None = None
        #: When the link's handshake last succeeded (wall time), None while it is down.
        self.up_since: float | None = None
        self.retries = 0  #: dials that failed in a row (nobody listens there)

    def drain(
        self,
        limit: int,
        dropped: Callable[[Monitor], None],
        retried: Callable[[Monitor], None] = lambda _m: None,
    ) -> bool:
        """Read up to ``limit`` events, calling ``dropped`` when the link drops (the peer
        may be restarting, and forget us) and ``retried`` when a connection attempt
        failed (nobody listens there now); True if more wait."""
        try:
            for _ in range(limit):
                if self.closed or not self.socket.getsockopt(EVENTS) & POLLIN:  # type: ignore[operator]
                    return False
                frames = self.socket.recv_multipart(NOBLOCK)
                if len(frames) == 2 and len(frames[0]) == 6:
                    event = int.from_bytes(frames[0][:2], sys.byteorder)
                    value = int.from_bytes(frames[0][2:], sys.byteorder)
                    self._event(event, value, dropped, retried)
        except zmq.ZMQError as exc:
            log.warning("transport.monitor_failed", peer=self.peer, error=str(exc))
            return False
        return True

    def _event(
        self,
        event: int,
        value: int,
        dropped: Callable[[Monitor], None],
        retried: Callable[[Monitor], None],
    ) -> None:
        if event == RETRIED:
            self.retries += 1
            retried(self)
            return
        if event == DISCONNECTED:
            self.up_since = None
        if event == DISCONNECTED and self.failed is None:
            dropped(self)
        elif event == DISCONNECTED and self.redial is None:
            loop = asyncio.get_running_loop()
            self.redial = loop.call_later(self.failed or 0.0, dropped, self)
        elif event == SUCCEEDED:
            self.retries = 0
            self.up_since = time.time()
            self.failed = None
            if self.redial is not None:
                self.redial.cancel()
                self.redial = None
            self.refusals.admitted(self.peer)
        elif event & HANDSHAKE_EVENTS and self.failed is None:  # once per DEALER
            self.failed = self.refusals.failed(self.peer, self.endpoint, event, value)

    def close(self) -> None:
        self.closed = True
        if self.redial is not None:
            self.redial.cancel()
        self.dealer.disable_monitor()
        self.socket.close(0)


class RouterEvents:
    """What libzmq did to inbound connections without telling the ROUTER's reader.

    Refused handshakes (a key not on the allow-list) and failed ones (wrong mechanism,
    junk) never become messages, and neither does a frame over ``MAXMSGSIZE``: libzmq
    drops that connection, which shows only as a disconnect. :attr:`refusals` says what
    failed, on this side (the ZAP handler tells it who was refused) and on the dialling
    one (the transport's DEALERs share it).
    """

    __slots__ = (
        "curve",
        "disconnects",
        "fd",
        "refusals",
        "router",
        "socket",
        "stats",
        "system",
        "watch",
    )

    def __init__(
        self,
        router: zmq.Socket[bytes],
        name: str,
        stats: TransportStats,
        system: str,
        curve: Curve | None = None,
    ) -> None:
        self.router = router
        self.stats = stats
        self.system = system
        self.curve = curve
        self.refusals = Refusals(system, stats, None if curve is None else curve.keys.public)
        #: Inbound connections libzmq dropped: their peer hung up, a frame over
        #: MAXMSGSIZE, or the transport shut them (no hello, too many links, a revoked
        #: key). Counted when the loop reads libzmq's event, after libzmq has let go of
        #: the connection: a moment after ``stats.by_reason`` counts one shut.
        self.disconnects = 0
        #: Closes connections that say no hello (set once the ROUTER is bound).
        self.watch: NewcomerWatch | None = None
        # REFUSED and FAILED, not EVENT_HANDSHAKE_FAILED_NO_DETAIL: with it watched, libzmq
        # 4.3.5 leaves a handshake that fails for want of a ZAP handler (a transport not yet
        # serving) hanging for good instead of closing it, and the peer never retries. (A
        # DEALER's monitor may watch it: it never runs ZAP.)
        self.socket: zmq.Socket[bytes] = router.get_monitor_socket(
            REFUSED | FAILED | DISCONNECTED | ACCEPTED, addr=name
        )
        self.fd = fd_of(self.socket)

    def drain(self, limit: int) -> bool:
        """Count up to ``limit`` events; True if more are queued.

        Refused handshakes (a key not on the allow-list) are unknown peers, told by the
        ZAP handler; disconnects are counted in :attr:`disconnects` and logged now and then.
        Accepts and disconnects, with the descriptor each names, go to :attr:`watch`.
        """
        sock, watch = self.socket, self.watch
        for _ in range(limit):
            if not sock.getsockopt(EVENTS) & POLLIN:  # type: ignore[operator]
                return False
            event = parse_monitor_message(sock.recv_multipart(NOBLOCK))
            kind, value = int(event["event"]), event["value"]
            if kind == REFUSED:
                self.stats.unknown_peer += 1
                self.stats.drop("handshake refused")
            elif kind == FAILED:
                self.refusals.handshake_failed(value)
            elif kind == ACCEPTED:
                if watch is not None:
                    watch.accepted(value)
            elif kind == DISCONNECTED:
                if watch is not None:
                    watch.gone(value)
                self.disconnects += 1
                if worth_logging(self.disconnects):
                    log.info(
                        "transport.disconnected",
                        system=self.system,
                        detail="a peer left, sent more than max_message_bytes or said no hello",
                        count=self.disconnects,
                    )
        return True

    def close(self) -> None:
        if self.watch is not None:
            self.watch.close()
        self.router.disable_monitor()
        self.socket.close(0)
