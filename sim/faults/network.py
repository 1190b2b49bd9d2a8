"""A seeded faulty network between actor systems in one process, on the virtual clock.

The deterministic simulation test (:mod:`btcap.sim.faults.run`) puts real agents on it: every
envelope goes through the codec as over ZeroMQ, and then, as one seeded
:class:`random.Random` decides, is dropped, delayed on the virtual clock (which reorders
it against later ones) or duplicated. On top of that, systems can be partitioned into
groups that do not hear each other, frozen (their traffic both ways is held and released
in one burst when they thaw) and crashed (their traffic is dropped until a new system of
the same name joins). Nothing here reads the wall clock, the global ``random`` or the
order of a hash.
"""

from __future__ import annotations

import asyncio
import random
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import anyio
import msgspec
from anyio.abc import TaskStatus

from btcap.actors import ManualClock
from btcap.transports import BROADCAST, Address, Codec, MessageRegistry
from btcap.transports.base import Deliver, Transport, TransportStats
from btcap.transports.codec import Envelope

__all__ = [
    "FaultyNetwork",
    "FaultyTransport",
    "LinkFaults",
    "NetCounters",
    "Tap",
]

#: Called with (sender, recipient, envelope) for each copy about to be delivered; returns
#: extra recipients (a test-only fault: misdelivery the protocol cannot be asked to survive).
Tap = Callable[[str, str, Envelope], Iterable[str]]


@dataclass(slots=True)
class LinkFaults:
    """What happens to each message: probabilities per copy, delays in clock seconds."""

    drop: float = 0.0
    duplicate: float = 0.0
    delay: float = 0.0  #: chance a copy is delayed
    max_delay_s: float = 0.0  #: a delayed copy arrives after uniform(0, max_delay_s)

    @property
    def clean(self) -> bool:
        return self.drop == 0.0 and self.duplicate == 0.0 and self.delay == 0.0


@dataclass(slots=True)
class NetCounters:
    """What the faults did, for tests and the trace summary."""

    sent: int = 0
    delivered: int = 0
    dropped: int = 0
    duplicated: int = 0
    delayed: int = 0
    cut: int = 0  #: dropped between partitions
    held: int = 0  #: held for a frozen system
    dead: int = 0  #: to or from a crashed system
    by_kind: dict[str, int] = field(default_factory=dict)


class FaultyNetwork:
    """The switchboard: one port per live system id, faults decided by ``rng``."""

    def __init__(self, clock: ManualClock, rng: random.Random, registry: MessageRegistry) -> None:
        self.clock = clock
        self.rng = rng
        self.codec = Codec(registry)
        self.faults = LinkFaults()
        self.counters = NetCounters()
        self.tap: Tap | None = None
        #: Called with (sender, envelope) for every message sent, before any fault.
        self.watch: Callable[[str, Envelope], None] | None = None
        #: Whether to lose a message outright (a test-only fault, with ``tap``).
        self.mute: Callable[[str, Envelope], bool] | None = None
        self._ports: dict[str, FaultyTransport] = {}
        self._group: dict[str, int] = {}
        self._oneway: set[tuple[str, str]] = set()
        self._frozen: dict[str, list[tuple[FaultyTransport, str, bytes]]] = {}
        self._dead: set[str] = set()

    # -- membership of the network --------------------------------------------------------
    def transport(self, system_id: str) -> FaultyTransport:
        """A port for ``system_id``; a crashed system's name can be taken again."""
        if system_id == BROADCAST:
            raise ValueError(f"system id {system_id!r} is reserved")
        old = self._ports.get(system_id)
        if old is not None and old.serving:
            raise ValueError(f"system id {system_id!r} is already on this network")
        self._dead.discard(system_id)
        port = FaultyTransport(self, system_id)
        self._ports[system_id] = port
        return port

    def _leave(self, port: FaultyTransport) -> None:
        if self._ports.get(port.system_id) is port:
            del self._ports[port.system_id]

    def names(self) -> list[str]:
        return list(self._ports)

    # -- faults -----------------------------------------------------------------------------
    def partition(self, groups: Iterable[Iterable[str]]) -> None:
        """Systems in different groups stop hearing each other; unnamed ones form group 0."""
        self._group = {name: i + 1 for i, group in enumerate(groups) for name in group}

    def cut_oneway(self, sender: str, receiver: str) -> None:
        """What ``sender`` sends ``receiver`` is lost (the other way still works)."""
        self._oneway.add((sender, receiver))

    def heal(self) -> None:
        """End partitions and one-way cuts."""
        self._group = {}
        self._oneway = set()

    def freeze(self, system_id: str) -> None:
        self._frozen.setdefault(system_id, [])

    def thaw(self, system_id: str) -> None:
        """Release what was held for ``system_id``, in order, in one burst."""
        for src, dest, data in self._frozen.pop(system_id, []):
            port = self._ports.get(dest)
            if port is not None and src.system_id not in self._dead:
                self._to(src, port, data)

    def crash(self, system_id: str) -> None:
        """Drop everything to and from ``system_id`` (its last words too) from now on."""
        self._dead.add(system_id)
        self._frozen.pop(system_id, None)

    @property
    def frozen(self) -> list[str]:
        return list(self._frozen)

    # -- routing ----------------------------------------------------------------------------
    def _count(self, what: str) -> None:
        kinds = self.counters.by_kind
        kinds[what] = kinds.get(what, 0) + 1

    def send(self, src: FaultyTransport, env: Envelope) -> None:
        if env.sender.system != src.system_id:
            src.stats.drop("forged sender")
            return
        self.counters.sent += 1
        self._count(type(env.msg).__name__)
        if self.watch is not None:
            self.watch(src.system_id, env)
        if self.mute is not None and self.mute(src.system_id, env):
            self.counters.dropped += 1
            return
        self._route(src, env)

    def _route(self, src: FaultyTransport, env: Envelope) -> None:
        name = src.system_id
        if name in self._dead or self._ports.get(name) is not src:
            self.counters.dead += 1
            return
        target = env.recipient.system
        if target == BROADCAST:
            dests = [p for n, p in self._ports.items() if n != name]
        elif (dest := self._ports.get(target)) is not None:
            dests = [dest]
        else:
            src.stats.undeliverable += 1
            return
        data = self.codec.encode(env)
        for dest in dests:
            self._to(src, dest, data)
            if self.tap is not None:
                for extra in self.tap(name, dest.system_id, env):
                    port = self._ports.get(extra)
                    if port is not None and port is not dest and port is not src:
                        to = Address(extra, env.recipient.path)
                        self._to(
                            src, port, self.codec.encode(msgspec.structs.replace(env, recipient=to))
                        )

    def _to(self, src: FaultyTransport, dest: FaultyTransport, data: bytes) -> None:
        a, b = src.system_id, dest.system_id
        if b in self._dead:
            self.counters.dead += 1
            return
        if self._group.get(a, 0) != self._group.get(b, 0) or (a, b) in self._oneway:
            self.counters.cut += 1
            return
        for frozen in (a, b):
            held = self._frozen.get(frozen)
            if held is not None:
                self.counters.held += 1
                held.append((src, b, data))
                return
        f, rng = self.faults, self.rng
        if f.clean:
            self._deliver(dest, data, 0.0)
            return
        if rng.random() < f.drop:
            self.counters.dropped += 1
            return
        copies = 2 if rng.random() < f.duplicate else 1
        self.counters.duplicated += copies - 1
        for _ in range(copies):
            delay = 0.0
            if rng.random() < f.delay:
                delay = rng.uniform(0.0, f.max_delay_s)
                self.counters.delayed += 1
            self._deliver(dest, data, delay)

    def _deliver(self, dest: FaultyTransport, data: bytes, delay: float) -> None:
        out = self.codec.decode(data)  # each copy its own objects, as off the wire
        self.counters.delivered += 1
        if delay > 0.0:
            self.clock.call_later(delay, dest.receive, out)
        else:
            dest.loop.call_soon(dest.receive, out)


class FaultyTransport(Transport):
    """One system's port on a :class:`FaultyNetwork`."""

    def __init__(self, network: FaultyNetwork, system_id: str) -> None:
        self.network = network
        self.system_id = system_id
        self.stats = TransportStats()
        self._deliver: Deliver | None = None
        self.loop: asyncio.AbstractEventLoop = asyncio.get_running_loop()

    @property
    def serving(self) -> bool:
        return self._deliver is not None

    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        self._deliver = deliver
        task_status.started()
        try:
            await anyio.sleep_forever()
        finally:
            self._deliver = None
            self.network._leave(self)

    def receive(self, env: Envelope) -> None:
        if self._deliver is not None and self.system_id not in self.network._dead:
            self.stats.received += 1
            self._deliver(env)

    def send(self, env: Envelope) -> None:
        self.stats.sent += 1
        self.network.send(self, env)

    def peers(self) -> frozenset[str]:
        return frozenset(n for n in self.network.names() if n != self.system_id)
