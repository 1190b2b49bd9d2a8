"""ZeroMQ socket set-up for :mod:`btcap.transports.zeromq`: peer ids, DEALERs, monitors.

A DEALER per peer carries our system id as its routing id; a connection monitor on it
tells when the link drops. The transport then replaces the DEALER by a fresh one with its
hello queued first: zmq would reconnect the old one by itself, but what was queued on it
since the drop would reach a peer restarted on the same endpoint before our hello, and
be dropped there as from an unknown peer.
"""

from __future__ import annotations

import asyncio
import secrets
import sys
import time
import uuid
from collections.abc import Callable
from typing import Any

import zmq
from zmq.backend import Socket as _BackendSocket
from zmq.utils.monitor import parse_monitor_message

from btcap.transports.base import BROADCAST, TransportStats
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.refusals import FAILED, HANDSHAKE_EVENTS, REFUSED, SUCCEEDED, Refusals
from btcap.transports.security import Curve

__all__ = [
    "EVENTS",
    "NOBLOCK",
    "POLLIN",
    "SCHEMES",
    "Monitor",
    "RouterEvents",
    "check_endpoint",
    "check_id",
    "fd_of",
    "open_dealer",
    "open_router",
    "parse_hello",
    "reject",
]

log = get_logger("btcap.transports")

# Plain ints: pyzmq's flag enums cost an enum call on every use.
NOBLOCK = int(zmq.NOBLOCK)
EVENTS = int(zmq.EVENTS)
POLLIN = int(zmq.POLLIN)
SCHEMES = ("tcp://", "ipc://", "inproc://")
_RECV_HWM = 10_000
_SEND_HWM = 10_000
_DEALER_MAX_IN = 16_384
"""A DEALER only sends: what else arrives is junk, and libzmq drops the connection."""
# ZMTP heartbeats (DEALERs): a PING a second, the connection dropped after 3 s of
# silence, else a cut link waits for TCP's backed-off retransmission once healed. libzmq's
# I/O thread pings and times out without the GIL, so a stalled event loop drops no healthy
# link. A dial into a partition gives up after 1 s (SYN retries: 1, 3, 7 s...) and is
# redone after RECONNECT_IVL.
_PING_MS, _PING_TIMEOUT_MS, _CONNECT_TIMEOUT_MS = 1000, 3000, 1000
# No heartbeats on the ROUTER: libzmq 4.3.5 (pyzmq 27's) aborts on assert "!_io_error" when
# a PING falls due on a link stopped at RCVHWM whose socket then failed (a peer flooded and
# reset it while we were busy). Kernel TCP keepalive (idle 5 s, 3 probes 1 s apart) drops a
# crashed host's inbound link instead; DEALERs still ping (tests/transports/*flood_reset*).
_KEEPALIVE_IDLE_S, _KEEPALIVE_INTVL_S, _KEEPALIVE_CNT = 5, 1, 3


def check_id(system_id: str) -> str | None:
    """Why ``system_id`` cannot name a system, or None if it can."""
    if not system_id or system_id == BROADCAST or "/" in system_id:
        return "expected a non-empty id without '/' that is not '*'"
    raw = system_id.encode()
    if len(raw) > 240:  # a zmq routing id holds 255, with room for a connection suffix
        return "longer than 240 bytes"
    if raw[0] == 0:
        return "starts with a NUL byte (reserved for ids zmq makes up)"
    return None


def fd_of(sock: zmq.Socket[bytes]) -> int:
    fd = sock.getsockopt(zmq.FD)
    assert isinstance(fd, int)
    return fd


def open_router(
    ctx: zmq.Context[Any],
    bind: str,
    curve: Curve | None,
    max_message_bytes: int,
    stats: TransportStats,
    system: str,
) -> tuple[zmq.Socket[bytes], RouterEvents]:
    """The ROUTER a transport receives on, bound to ``bind``, with its event monitor."""
    sock: zmq.Socket[bytes] = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.RCVHWM, _RECV_HWM)
    sock.setsockopt(zmq.MAXMSGSIZE, max_message_bytes)
    sock.setsockopt(zmq.TCP_KEEPALIVE, 1)  # not HEARTBEAT_IVL: see _KEEPALIVE_IDLE_S
    sock.setsockopt(zmq.TCP_KEEPALIVE_IDLE, _KEEPALIVE_IDLE_S)
    sock.setsockopt(zmq.TCP_KEEPALIVE_INTVL, _KEEPALIVE_INTVL_S)
    sock.setsockopt(zmq.TCP_KEEPALIVE_CNT, _KEEPALIVE_CNT)
    if curve is not None:
        curve.server(sock)
    # No ROUTER_HANDOVER, with keys or without: every connection has a routing id of its
    # own (see open_dealer), so a peer that reconnects never collides with its old link,
    # and one that takes another's routing id (learnt, or guessed: without keys it is the
    # name) gets a link of its own instead of cutting the real one off for good.
    name = f"inproc://zmq-transport-router-{uuid.uuid4().hex}"
    events = RouterEvents(sock, name, stats, system, curve)
    try:
        sock.bind(bind)
    except zmq.ZMQError as exc:
        events.close()
        sock.close(0)
        raise ValueError(f"cannot bind {bind!r}: {exc}") from None
    return sock, events


def reject(stats: TransportStats, system: str, reason: str, ident: bytes, detail: str) -> None:
    """Count a dropped input; log it while :func:`worth_logging` says so (a flood of junk
    must not become a flood of log lines)."""
    stats.drop(reason)
    n = stats.by_reason[reason]
    if worth_logging(n):
        log.warning(
            "transport.dropped",
            system=system,
            peer=ident[:64].decode(errors="replace"),
            reason=reason,
            detail=detail,
            count=n,
        )


COPY_THRESHOLD = 65_536
"""Smaller payloads are copied into the frame (cheaper than tracking a zero-copy buffer)."""
send_frame = _BackendSocket.send
"""pyzmq's compiled send, without the Python wrapper ``zmq.Socket.send`` puts around it
for DRAFT options we never use: ~0.7 us less per message, and every message is sent."""


def write(
    sock: zmq.Socket[bytes],
    frame: bytes,
    max_bytes: int,
    stats: TransportStats,
    system: str,
    to: str,
) -> None:
    """Send one frame to peer ``to`` without blocking; what cannot go is counted."""
    if len(frame) > max_bytes:
        # The peer would drop the connection (and what is queued behind the frame).
        stats.undeliverable += 1
        reject(stats, system, "too large to send", to.encode(), f"{len(frame)} bytes")
        return
    try:
        if len(frame) < COPY_THRESHOLD:
            send_frame(sock, frame, NOBLOCK)
        else:
            send_frame(sock, frame, NOBLOCK, False)
    except zmq.ZMQError as exc:  # zmq.Again: the peer's queue is full
        unsent(stats, to, exc)
    else:
        stats.sent += 1


def unsent(stats: TransportStats, to: str, exc: zmq.ZMQError) -> None:
    """Count a frame the peer ``to`` could not be sent (zmq.Again: its queue is full)."""
    stats.undeliverable += 1
    why = "backed up" if exc.errno == zmq.EAGAIN else exc.strerror
    stats.drop(f"peer {to} {why}")


def parse_hello(ident: bytes, payload: bytes, own_id: str) -> tuple[str, str]:
    """The peer id and endpoint a hello announces; ValueError says what is wrong."""
    try:
        peer = ident.decode()
        endpoint = payload.decode()
    except UnicodeDecodeError:
        raise ValueError("id or endpoint not UTF-8") from None
    if (why := check_id(peer)) is not None:
        raise ValueError(why)
    if not endpoint.startswith(SCHEMES) or len(endpoint) > 1024:
        raise ValueError(f"endpoint {endpoint[:80]!r}")
    if peer == own_id:
        raise ValueError("another system uses our id")
    return peer, endpoint


def open_dealer(
    ctx: zmq.Context[Any], own_id: bytes, peer: str, endpoint: str, events: RouterEvents
) -> tuple[zmq.Socket[bytes], Monitor | None]:
    """A DEALER connected to ``peer`` at ``endpoint``, with its monitor (none for inproc).

    With keys (``events.curve``) it only completes a handshake with a server holding
    ``peer``'s key; a failed handshake is told to ``events.refusals``.
    """
    curve = events.curve
    if curve is not None and endpoint.startswith("inproc://"):
        raise ValueError(f"peer {peer}: cannot reach {endpoint!r} with keys (not encrypted)")
    sock: zmq.Socket[bytes] = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    # Our name and a fresh suffix per connection: a restart never collides with its old,
    # dead link. With keys ZAP names the sender; without, the part before the "/" does
    # (ids have no "/").
    routing_id = own_id + b"/" + secrets.token_hex(6).encode()
    sock.setsockopt(zmq.ROUTING_ID, routing_id)
    sock.setsockopt(zmq.SNDHWM, _SEND_HWM)
    sock.setsockopt(zmq.RCVHWM, 1)
    sock.setsockopt(zmq.MAXMSGSIZE, _DEALER_MAX_IN)
    sock.setsockopt(zmq.HEARTBEAT_IVL, _PING_MS)
    sock.setsockopt(zmq.HEARTBEAT_TIMEOUT, _PING_TIMEOUT_MS)
    sock.setsockopt(zmq.CONNECT_TIMEOUT, _CONNECT_TIMEOUT_MS)
    if curve is not None:
        try:
            curve.client(sock, peer)
        except ValueError:
            sock.close(0)
            raise
    monitor = None
    if not endpoint.startswith("inproc://"):
        # A peer that restarts on the same endpoint has forgotten us: a monitor tells us
        # the link dropped, to relink with a hello first (see the module's docstring).
        # It must watch before connecting, or an early drop may go unseen.
        # (pyzmq names monitors after the socket's fd, which a closed one may still
        # hold while zmq reaps it: a fresh name never collides.)
        name = f"inproc://zmq-transport-monitor-{uuid.uuid4().hex}"
        try:
            watch = _DISCONNECTED | _RETRIED | HANDSHAKE_EVENTS
            socket = sock.get_monitor_socket(watch, addr=name)
        except zmq.ZMQError as exc:
            log.warning("transport.no_monitor", peer=peer, error=str(exc))
        else:
            monitor = Monitor(peer, sock, socket, endpoint, events.refusals)
    try:
        sock.connect(endpoint)
    except zmq.ZMQError as exc:
        if monitor is not None:
            monitor.close()
        sock.close(0)
        raise ValueError(f"peer {peer}: cannot connect to {endpoint!r}: {exc}") from None
    return sock, monitor


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
        if event == _RETRIED:
            self.retries += 1
            retried(self)
            return
        if event == _DISCONNECTED:
            self.up_since = None
        if event == _DISCONNECTED and self.failed is None:
            dropped(self)
        elif event == _DISCONNECTED and self.redial is None:
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


# The ROUTER's monitor watches REFUSED and FAILED, not EVENT_HANDSHAKE_FAILED_NO_DETAIL:
# with it watched, libzmq 4.3.5 leaves a handshake that fails for want of a ZAP handler (a
# transport not yet serving) hanging for good instead of closing it, and the peer never
# retries. (A DEALER's monitor may: it never runs ZAP.)
_DISCONNECTED = int(zmq.EVENT_DISCONNECTED)
_RETRIED = int(zmq.EVENT_CONNECT_RETRIED)


class RouterEvents:
    """What libzmq did to inbound connections without telling the ROUTER's reader.

    Refused handshakes (a key not on the allow-list) and failed ones (wrong mechanism,
    junk) never become messages, and neither does a frame over ``MAXMSGSIZE``: libzmq
    drops that connection, which shows only as a disconnect. :attr:`refusals` says what
    failed, on this side (the ZAP handler tells it who was refused) and on the dialling
    one (the transport's DEALERs share it).
    """

    __slots__ = ("curve", "disconnects", "fd", "refusals", "router", "socket", "stats", "system")

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
        self.disconnects = 0
        self.socket: zmq.Socket[bytes] = router.get_monitor_socket(
            REFUSED | FAILED | _DISCONNECTED, addr=name
        )
        self.fd = fd_of(self.socket)

    def drain(self, limit: int) -> bool:
        """Count up to ``limit`` events; True if more are queued.

        Refused handshakes (a key not on the allow-list) are unknown peers, told by the
        ZAP handler; disconnects are counted in :attr:`disconnects` and logged now and then.
        """
        sock = self.socket
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
            elif kind == _DISCONNECTED:
                self.disconnects += 1
                if worth_logging(self.disconnects):
                    log.info(
                        "transport.disconnected",
                        system=self.system,
                        detail="a peer left, or sent more than max_message_bytes",
                        count=self.disconnects,
                    )
        return True

    def close(self) -> None:
        self.router.disable_monitor()
        self.socket.close(0)


def check_endpoint(endpoint: str, *, dial: bool) -> str | None:
    """Why ``endpoint`` cannot be bound (or, ``dial``: dialled by peers), or None.

    libzmq wraps a tcp port above 65535 round to another port and binds that, so a typo
    would listen where no peer looks: refused here, with the other malformed endpoints.
    """
    if not endpoint.startswith(SCHEMES):
        return "expected a tcp://, ipc:// or inproc:// endpoint"
    if not endpoint.startswith("tcp://"):
        return None if endpoint.partition("://")[2] else "expected a name after the scheme"
    host, colon, port = endpoint.removeprefix("tcp://").rpartition(":")
    if not colon or not host:
        return "expected tcp://HOST:PORT"
    if dial and (port == "*" or "*" in host):
        return "expected a host and port peers can dial, not a wildcard"
    if port != "*" and not (port.isdigit() and int(port) <= 65535):
        return f"port {port!r}: expected 0 to 65535" + ("" if dial else " or *")
    return None


def check_transport_args(system_id: str, bind: str, advertise: str | None, max_bytes: int) -> None:
    """What a ZmqTransport is given, checked before any socket opens."""
    if (why := check_id(system_id)) is not None:
        raise ValueError(f"system id {system_id!r}: {why}")
    if (why := check_endpoint(bind, dial=False)) is not None:
        raise ValueError(f"cannot bind {bind!r}: {why}")
    if advertise is not None and (why := check_endpoint(advertise, dial=True)) is not None:
        raise ValueError(f"advertise {advertise!r}: {why}")
    if max_bytes < 1024:
        raise ValueError(f"max_message_bytes {max_bytes}: expected at least 1024")
