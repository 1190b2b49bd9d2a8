"""The ZeroMQ context and receive path of :mod:`btcap.transports.zeromq`, tuned for speed.

Receiving reads a part's ``more`` flag rather than asking ``RCVMORE`` (pyzmq turns every
socket option into an enum on each call) and keeps the body in the frame's buffer, which
the codec decodes without a copy: a path every message takes, so a message comes back as
a tuple, not a list of parts (btcap's have one part after the routing id).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from typing import Any

import zmq

__all__ = [
    "EVENTS",
    "NOBLOCK",
    "POLLIN",
    "Received",
    "allow_sockets",
    "fd_of",
    "read_plain",
    "read_secure",
    "remove_ipc_file",
]

# Plain ints: pyzmq's flag enums cost an enum call on every use.
NOBLOCK = int(zmq.NOBLOCK)
EVENTS = int(zmq.EVENTS)
POLLIN = int(zmq.POLLIN)

Received = tuple[bytes, memoryview, int]
"""A received message: who sent it (its routing id's name), its first part's buffer and
how many parts followed that one (read and dropped: a message of btcap's has one)."""


def allow_sockets(ctx: zmq.Context[Any]) -> None:
    """Each peer costs a DEALER and a monitor pair: libzmq's default of 1023 sockets per
    context runs out at about 340 peers, sooner for robots sharing a process. Raised to
    16,384; this only takes effect before the context's first socket."""
    limit = min(int(ctx.get(zmq.SOCKET_LIMIT)), 16_384)
    if int(ctx.get(zmq.MAX_SOCKETS)) < limit:
        ctx.set(zmq.MAX_SOCKETS, limit)


def fd_of(sock: zmq.Socket[bytes]) -> int:
    """The descriptor the event loop watches for ``sock``'s input (then read ``EVENTS``:
    it is edge-triggered)."""
    fd = sock.getsockopt(zmq.FD)
    assert isinstance(fd, int)
    return fd


def read_plain(recv: Callable[..., Any]) -> Received:
    """One message from a ROUTER without keys, named by what its routing id claims (see
    ``open_dealer``). Raises ``zmq.Again`` when nothing is queued."""
    ident: bytes = recv(NOBLOCK).partition(b"/")[0]
    part = recv(NOBLOCK, copy=False)
    return ident, part.buffer, _rest(recv, part) if part.more else 0


def read_secure(recv: Callable[..., Any]) -> tuple[bytes, zmq.Frame, int]:
    """One message from a ROUTER with keys: its routing id, its first part as a frame
    (ZAP's ``User-Id`` is a property of every part) and how many parts followed it."""
    ident: bytes = recv(NOBLOCK)
    part = recv(NOBLOCK, copy=False)
    return ident, part, _rest(recv, part) if part.more else 0


def _rest(recv: Callable[..., Any], part: zmq.Frame) -> int:
    extra = 0
    while part.more:
        part = recv(NOBLOCK, copy=False)
        extra += 1
    return extra


def remove_ipc_file(endpoint: str) -> None:
    """Delete the socket file of an ``ipc://`` endpoint this process bound (libzmq removes
    it only later, from its own thread, and not at all if the process exits first)."""
    if endpoint.startswith("ipc://") and not endpoint.startswith("ipc://@"):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(endpoint.removeprefix("ipc://"))
