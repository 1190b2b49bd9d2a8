"""ZeroMQ socket set-up for :mod:`btcap.transports.zeromq`: peer ids, DEALERs, monitors.

A DEALER per peer carries our system id as its routing id; a connection monitor on it
tells when zmq reconnected, so the transport can say hello again to a peer that
restarted on the same endpoint.
"""

from __future__ import annotations

import sys
import uuid
from typing import Any

import zmq

from btcap.transports.base import BROADCAST
from btcap.transports.log import get_logger

__all__ = ["EVENTS", "NOBLOCK", "POLLIN", "Monitor", "check_id", "open_dealer"]

log = get_logger("btcap.transports")

# Plain ints: pyzmq's flag enums cost an enum call on every use.
NOBLOCK = int(zmq.NOBLOCK)
EVENTS = int(zmq.EVENTS)
POLLIN = int(zmq.POLLIN)
_SEND_HWM = 10_000


def check_id(system_id: str) -> str | None:
    """Why ``system_id`` cannot name a system, or None if it can."""
    if not system_id or system_id == BROADCAST or "/" in system_id:
        return "expected a non-empty id without '/' that is not '*'"
    raw = system_id.encode()
    if len(raw) > 255:
        return "longer than 255 bytes"
    if raw[0] == 0:
        return "starts with a NUL byte (reserved for ids zmq makes up)"
    return None


def open_dealer(
    ctx: zmq.Context[Any], own_id: bytes, peer: str, endpoint: str
) -> tuple[zmq.Socket[bytes], Monitor | None]:
    """A DEALER connected to ``peer`` at ``endpoint``, with its monitor (none for inproc)."""
    sock: zmq.Socket[bytes] = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.ROUTING_ID, own_id)
    sock.setsockopt(zmq.SNDHWM, _SEND_HWM)
    monitor = None
    if not endpoint.startswith("inproc://"):
        # A peer that restarts on the same endpoint gets our DEALER back by zmq's
        # reconnect, but has forgotten us: a monitor tells us to say hello again.
        # It must watch before connecting, or the first connection may go unseen.
        # (pyzmq names monitors after the socket's fd, which a closed one may still
        # hold while zmq reaps it: a fresh name never collides.)
        name = f"inproc://zmq-transport-monitor-{uuid.uuid4().hex}"
        try:
            events = sock.get_monitor_socket(zmq.EVENT_CONNECTED, addr=name)
        except zmq.ZMQError as exc:
            log.warning("transport.no_monitor", peer=peer, error=str(exc))
        else:
            monitor = Monitor(peer, sock, events)
    try:
        sock.connect(endpoint)
    except zmq.ZMQError as exc:
        if monitor is not None:
            monitor.close()
        sock.close(0)
        raise ValueError(f"peer {peer}: cannot connect to {endpoint!r}: {exc}") from None
    return sock, monitor


class Monitor:
    """Connection events of one DEALER, read from its zmq monitor socket."""

    __slots__ = ("closed", "connects", "dealer", "fd", "peer", "socket")

    def __init__(self, peer: str, dealer: zmq.Socket[bytes], socket: zmq.Socket[bytes]) -> None:
        self.peer = peer
        self.dealer = dealer
        self.socket = socket
        fd = socket.getsockopt(zmq.FD)
        assert isinstance(fd, int)
        self.fd = fd
        self.connects = 0
        self.closed = False

    def pending(self) -> bool:
        return bool(self.socket.getsockopt(EVENTS) & POLLIN)  # type: ignore[operator]

    def connected(self) -> bool:
        """Read one event; True (and counted) if it is a new connection."""
        frames = self.socket.recv_multipart(NOBLOCK)
        if len(frames) == 2 and len(frames[0]) == 6:
            event = int.from_bytes(frames[0][:2], sys.byteorder)
            if event == zmq.EVENT_CONNECTED:
                self.connects += 1
                return True
        return False

    def close(self) -> None:
        self.closed = True
        self.dealer.disable_monitor()
        self.socket.close(0)
