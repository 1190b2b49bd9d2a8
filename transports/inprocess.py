"""Joins several actor systems inside one process (tests, the simulation)."""

from __future__ import annotations

import asyncio
from collections.abc import Collection

import anyio
from anyio.abc import TaskStatus

from btcap.transports.base import BROADCAST, Deliver, Transport, TransportStats
from btcap.transports.codec import Codec, CodecError, Envelope
from btcap.transports.message import MessageRegistry

__all__ = ["InProcessNetwork", "InProcessTransport"]


class InProcessNetwork:
    """A switchboard of in-process transports, with partitions for failure tests.

    By default every envelope goes through the codec, so systems never share mutable
    messages and a type that would not survive the wire fails here first.
    """

    def __init__(self, registry: MessageRegistry | None = None, *, encode: bool = True) -> None:
        self._members: dict[str, InProcessTransport] = {}
        #: Systems cut off, each with the systems it still reaches (see :meth:`isolate`).
        self._cut: dict[str, frozenset[str]] = {}
        self._everyone: frozenset[str] | None = None  # the members' names, until one changes
        self.codec = Codec(registry or MessageRegistry()) if encode else None

    def transport(self, system_id: str) -> InProcessTransport:
        if system_id in self._members or system_id == BROADCAST:
            raise ValueError(f"system id {system_id!r} is already on this network or reserved")
        t = InProcessTransport(self, system_id)
        self._members[system_id] = t
        self._everyone = None
        return t

    def isolate(self, system_id: str, *, keep: Collection[str] = ()) -> None:
        """Cut a system off (it neither sends nor receives) until :meth:`heal`, except to
        and from the systems in ``keep``: a simulated robot cut off from its team still
        hears its own body, which the simulation stands in for."""
        self._cut[system_id] = frozenset(keep)

    def heal(self, system_id: str) -> None:
        self._cut.pop(system_id, None)

    def _leave(self, system_id: str) -> None:
        self._members.pop(system_id, None)
        self._cut.pop(system_id, None)
        self._everyone = None

    def _names(self) -> frozenset[str]:
        """Every system on the network (kept until one joins or leaves: a team asks often)."""
        if self._everyone is None:
            self._everyone = frozenset(self._members)
        return self._everyone

    def _route(self, src: InProcessTransport, env: Envelope) -> None:
        cut = self._cut
        kept = cut.get(src.system_id)
        if kept is not None and env.recipient.system not in kept:
            src.stats.drop("isolated")
            return
        if env.sender.system != src.system_id:
            # The network knows who sends: a system may not speak as another.
            src.stats.drop("forged sender")
            return
        target = env.recipient.system
        if target == BROADCAST:
            dests = [t for sid, t in self._members.items() if sid != src.system_id]
        else:
            dest = self._members.get(target)
            if dest is None:
                src.stats.undeliverable += 1
                src.stats.drop(f"no peer {target}")
                return
            dests = [dest]
        for dest in dests:
            if cut and dest.system_id in cut and src.system_id not in cut[dest.system_id]:
                src.stats.drop("isolated")
                continue
            if dest._deliver is None:
                src.stats.drop("not serving")
                continue
            out = env
            if self.codec is not None:
                try:
                    out = self.codec.decode(self.codec.encode(env))
                except CodecError as exc:
                    src.stats.malformed += 1
                    raise CodecError(f"envelope to {target}: {exc}") from None
            src.stats.sent += 1
            dest._loop.call_soon(dest._receive, out)


class InProcessTransport(Transport):
    """One system's port on an :class:`InProcessNetwork`; delivery is asynchronous."""

    def __init__(self, network: InProcessNetwork, system_id: str) -> None:
        self._network = network
        self.system_id = system_id
        self.stats = TransportStats()
        self._deliver: Deliver | None = None
        self._loop: asyncio.AbstractEventLoop

    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        self._loop = asyncio.get_running_loop()
        self._deliver = deliver
        task_status.started()
        try:
            await anyio.sleep_forever()
        finally:
            self._deliver = None
            self._network._leave(self.system_id)

    def _receive(self, env: Envelope) -> None:
        if self._deliver is not None:
            self.stats.received += 1
            self._deliver(env)

    def send(self, env: Envelope) -> None:
        self._network._route(self, env)

    def peers(self) -> frozenset[str]:
        return self._network._names() - {self.system_id}
