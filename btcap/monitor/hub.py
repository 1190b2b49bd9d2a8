"""The connected pages' queues: every batch encoded once and queued for each page.

A client gets the whole picture when it connects (``{"type": "snapshot", "state": ...}``)
and then every batch of events (``{"type": "events", "events": [...]}``), one message per
batch. A client too slow to keep up is not waited for: its backlog is replaced by a
fresh snapshot. When the server stops, each client's queue ends with :data:`END`: the
page is sent everything before it (a live run's ``finished`` event) and then closed.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

import msgspec

from btcap.monitor.view import Event

__all__ = ["BACKLOG", "END", "Hub"]

#: Batches a client may fall behind before it is sent a snapshot instead.
BACKLOG = 32
#: The last item of a client's queue: nothing follows, close its socket.
END = b""

_encode = msgspec.json.Encoder()


class Hub:
    """The connected pages' queues: every batch encoded once, queued for each."""

    def __init__(self) -> None:
        self._clients: set[asyncio.Queue[bytes]] = set()
        self.snapshot: Callable[[], dict[str, Any]] = dict
        self.sent = 0  #: messages queued, over all clients (for tests and the benchmark)

    def join(self) -> asyncio.Queue[bytes]:
        q: asyncio.Queue[bytes] = asyncio.Queue(BACKLOG)
        q.put_nowait(self._snapshot_msg())
        self._clients.add(q)
        return q

    def leave(self, q: asyncio.Queue[bytes]) -> None:
        self._clients.discard(q)

    @property
    def clients(self) -> int:
        return len(self._clients)

    def _snapshot_msg(self) -> bytes:
        return _encode.encode({"type": "snapshot", "state": self.snapshot()})

    def publish(self, batch: list[Event]) -> None:
        if self._clients:
            self._send(_encode.encode({"type": "events", "events": batch}))

    def reset(self) -> None:
        """Every page starts over from a snapshot (a replay jumped)."""
        for q in self._clients:
            _drain(q)
        if self._clients:
            self._send(self._snapshot_msg())

    def close(self) -> None:
        """Every page is to be sent what is queued for it, then :data:`END`."""
        for q in self._clients:
            if q.full():  # too far behind: the picture now, then the end
                _drain(q)
                q.put_nowait(self._snapshot_msg())
            q.put_nowait(END)

    def _send(self, msg: bytes) -> None:
        for q in self._clients:
            if q.full():
                _drain(q)
                q.put_nowait(self._snapshot_msg())
            else:
                q.put_nowait(msg)
            self.sent += 1


def _drain(q: asyncio.Queue[bytes]) -> None:
    while not q.empty():
        q.get_nowait()
