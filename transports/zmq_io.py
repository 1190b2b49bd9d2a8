"""The ZeroMQ context and receive path of :mod:`btcap.transports.zeromq`, tuned for speed.

Receiving reads a part's ``more`` flag rather than asking ``RCVMORE`` (pyzmq turns every
socket option into an enum on each call) and keeps the body in the frame's buffer, which
the codec decodes without a copy: a path every message takes.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from typing import Any

import zmq

__all__ = ["allow_sockets", "read_frames", "read_plain", "remove_ipc_file"]

NOBLOCK = int(zmq.NOBLOCK)


def allow_sockets(ctx: zmq.Context[Any]) -> None:
    """Each peer costs a DEALER and a monitor pair: libzmq's default of 1023 sockets per
    context runs out at about 340 peers, sooner for robots sharing a process. Raised to
    16,384; this only takes effect before the context's first socket."""
    limit = min(int(ctx.get(zmq.SOCKET_LIMIT)), 16_384)
    if int(ctx.get(zmq.MAX_SOCKETS)) < limit:
        ctx.set(zmq.MAX_SOCKETS, limit)


def read_plain(recv: Callable[..., Any]) -> list[bytes | memoryview]:
    """One message from a ROUTER without keys: the name its routing id claims (see
    ``open_dealer``), then its parts' buffers (a ROUTER's id always has one after it).
    Raises ``zmq.Again`` when nothing is queued."""
    frames: list[bytes | memoryview] = [recv(NOBLOCK).partition(b"/")[0]]
    part = recv(NOBLOCK, copy=False)
    frames.append(part.buffer)
    while part.more:
        part = recv(NOBLOCK, copy=False)
        frames.append(part.buffer)
    return frames


def read_frames(recv: Callable[..., Any]) -> list[zmq.Frame]:
    """One message as frames (with keys: ZAP's ``User-Id`` is a frame property)."""
    parts: list[zmq.Frame] = [recv(NOBLOCK, copy=False)]
    while parts[-1].more:
        parts.append(recv(NOBLOCK, copy=False))
    return parts


def remove_ipc_file(endpoint: str) -> None:
    """Delete the socket file of an ``ipc://`` endpoint this process bound (libzmq removes
    it only later, from its own thread, and not at all if the process exits first)."""
    if endpoint.startswith("ipc://") and not endpoint.startswith("ipc://@"):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(endpoint.removeprefix("ipc://"))
