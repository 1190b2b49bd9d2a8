"""ZeroMQ sockets for :mod:`btcap.transports.zeromq`: the ROUTER, a DEALER per peer, sends.

A DEALER per peer carries our system id as its routing id; a connection monitor on it
(:mod:`~btcap.transports.zmq_monitors`) tells when the link drops. The transport then
replaces the DEALER by a fresh one with its hello queued first: zmq would reconnect the
old one by itself, but what was queued on it since the drop would reach a peer restarted
on the same endpoint before our hello, and be dropped there as from an unknown peer.
"""

from __future__ import annotations

import secrets
import uuid
from typing import Any

import zmq
from zmq.backend import Socket as _BackendSocket

from btcap.transports.base import TransportStats
from btcap.transports.log import get_logger, worth_logging
from btcap.transports.refusals import HANDSHAKE_EVENTS
from btcap.transports.security import Curve
from btcap.transports.zmq_endpoints import NewcomerLimits
from btcap.transports.zmq_io import NOBLOCK
from btcap.transports.zmq_monitors import DISCONNECTED, RETRIED, Monitor, RouterEvents
from btcap.transports.zmq_newcomers import NewcomerWatch

__all__ = [
    "COPY_THRESHOLD",
    "open_dealer",
    "open_router",
    "reject",
    "send_frame",
    "unsent",
    "write",
]

log = get_logger(__name__)

_RECV_HWM = 10_000
_SEND_HWM = 10_000
_DEALER_MAX_IN = 16_384
"""A DEALER only sends: peers never answer on it, so anything beyond a handshake that
arrives there is junk, and libzmq drops the connection instead of queueing it."""
# ZMTP heartbeats on the DEALERs: each PINGs every _PING_MS and drops its connection if
# nothing at all arrives within _PING_TIMEOUT_MS of a PING. Without them a cut link stays
# up, and after the heal nothing flows until TCP's backed-off retransmission timer fires
# (seconds to minutes). A dropped DEALER is relinked (Monitor, _relink), so a cut longer
# than the timeout heals within a redial. libzmq's I/O thread sends and answers PINGs and
# runs the timers, without the GIL: a stalled event loop (a second under CPU load) never
# drops a healthy link; only one with no traffic at all for 3-4 s is. 1 s pings cost next
# to nothing (a few bytes each way per link); each side times out for itself, so
# HEARTBEAT_TTL is not needed, nor TCP_MAXRT (TCP_USER_TIMEOUT on Linux), which would only
# drop the same links later.
_PING_MS = 1000
_PING_TIMEOUT_MS = 3000
_CONNECT_TIMEOUT_MS = 1000
"""A dial into a partition gets no answer, and its SYN is retried by the kernel after 1,
3, 7, 15... s: given up after 1 s and redialled after zmq's RECONNECT_IVL (100 ms)
instead, so a relinked peer is reached about a second after the heal at most. A SYN's
round trip is the network's alone (no process runs in it): 1 s is ample on a LAN."""
# The ROUTER sends no heartbeats: libzmq 4.3.5 (the newest release, bundled by pyzmq 27)
# aborts the process on a PING falling due on a connection whose input stopped at RCVHWM
# and whose socket then failed (a peer that floods and resets, with the agent too busy to
# drain in time): assertion "!_io_error", stream_engine_base.cpp:310. TCP keepalive,
# kept by the kernel, drops a crashed host's inbound link instead (~5 s idle, then 3
# probes 1 s apart); a DEALER's own PINGs still drop a silent peer from the sending side
# (tests/transports/*flood_reset*).
_KEEPALIVE_IDLE_S = 5
_KEEPALIVE_INTVL_S = 1
_KEEPALIVE_CNT = 3


def open_router(
    ctx: zmq.Context[Any],
    bind: str,
    curve: Curve | None,
    max_message_bytes: int,
    stats: TransportStats,
    system: str,
    limits: NewcomerLimits,
) -> tuple[zmq.Socket[bytes], RouterEvents]:
    """The ROUTER a transport receives on, bound to ``bind``, with its event monitor,
    which closes connections that say no hello in time (``limits``: see
    :mod:`~btcap.transports.newcomers`)."""
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
    bound = sock.getsockopt_string(zmq.LAST_ENDPOINT)
    events.watch = NewcomerWatch(bound, stats, system, *limits)
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
            watch = DISCONNECTED | RETRIED | HANDSHAKE_EVENTS
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
