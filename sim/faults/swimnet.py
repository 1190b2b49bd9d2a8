"""The membership protocol's sans-IO core over a seeded discrete-event network.

Hundreds of robots for simulated hours are too many for full agents, so this drives the
real :class:`~btcap.team.core.swim.Swim` of each robot directly: every robot's periods
start at a seeded phase, every message is delivered after a seeded latency or lost with
a seeded chance (per link, so a test can make one link lossy), and robots can be killed
(silent from then on). Same seed, same run. Used by the membership tests and by
``python -m btcap.bench membership`` for the large teams.
"""

from __future__ import annotations

import heapq
import random
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec

from btcap.team.core.members import TeamEvent
from btcap.team.core.swim import Step, Swim, SwimParams
from btcap.team.messages import Goodbye, Heartbeat, ProbeRequest, Vouch
from btcap.transports.message import Message

__all__ = ["Event", "SwimNet"]

#: Bytes an envelope adds around a message on the wire (addresses, kind, ids): an
#: estimate from the codec's envelopes of membership messages.
ENVELOPE_BYTES = 40


@dataclass(frozen=True, slots=True)
class Event:
    """``observer`` saw ``event`` of ``robot`` at ``at``."""

    at: float
    observer: str
    event: TeamEvent
    robot: str


@dataclass(slots=True)
class _Robot:
    swim: Swim
    alive: bool = True
    sent: int = 0
    bytes: int = 0
    counted: Counter[str] = field(default_factory=Counter)


class SwimNet:
    """``names`` robots running :class:`Swim` with ``params``; everybody knows everybody
    at time 0 (joined) unless ``joined`` is False."""

    def __init__(
        self,
        names: list[str],
        params: SwimParams,
        *,
        seed: int = 0,
        loss: float = 0.0,
        latency_s: tuple[float, float] = (0.001, 0.005),
        joined: bool = True,
    ) -> None:
        self.params = params
        self.loss = loss
        self.latency_s = latency_s
        self.now = 0.0
        self.events: list[Event] = []
        self.link_loss: dict[tuple[str, str], float] = {}
        #: Called with (sender, recipient, message) for every message sent; True: drop it.
        self.intercept: Callable[[str, str, Message], bool] | None = None
        self.counting = True
        self._rng = random.Random(f"net {seed}")
        self._queue: list[tuple[float, int, int, str, str, Message | None]] = []
        self._seq = 0
        self._enc = msgspec.msgpack.Encoder()
        self.robots: dict[str, _Robot] = {}
        for i, name in enumerate(names):
            swim = Swim(name, 1000 + i, params, random.Random(f"swim {seed} {name}"))
            self.robots[name] = _Robot(swim)
        if joined:
            for name, r in self.robots.items():
                for other, o in self.robots.items():
                    if other != name:
                        r.swim.table.heartbeat(other, o.swim.incarnation, 0, 0.0)
        phase = random.Random(f"phase {seed}")
        for name in names:
            self._at(phase.uniform(0, params.period_s), _TICK, name)

    # -- driving ------------------------------------------------------------------------
    def _at(
        self, t: float, kind: int, to: str, sender: str = "", msg: Message | None = None
    ) -> None:
        self._seq += 1
        heapq.heappush(self._queue, (t, self._seq, kind, to, sender, msg))

    def send(self, sender: str, to: str, msg: Message) -> None:
        """``sender`` sends ``msg`` to ``to`` (lost, delayed, counted as the network says)."""
        r = self.robots.get(sender)
        if r is not None and self.counting:
            r.sent += 1
            r.bytes += len(self._enc.encode(msg)) + ENVELOPE_BYTES
            r.counted[type(msg).__name__] += 1
        if self.intercept is not None and self.intercept(sender, to, msg):
            return
        self.transmit(sender, to, msg)

    def transmit(self, sender: str, to: str, msg: Message) -> None:
        """Put ``msg`` on the wire, past :attr:`intercept` (lost or delayed as usual)."""
        loss = self.link_loss.get((sender, to), self.loss)
        if loss and self._rng.random() < loss:
            return
        lo, hi = self.latency_s
        self._at(self.now + self._rng.uniform(lo, hi), _DELIVER, to, sender, msg)

    def inject(self, at: float, sender: str, to: str, msg: Message) -> None:
        """Deliver ``msg`` to ``to`` at ``at`` from ``sender``, who need not be a robot of
        the net (a made-up member: what is sent to it goes nowhere)."""
        self._at(at, _DELIVER, to, sender, msg)

    def run_until(self, until: float) -> None:
        queue = self._queue
        while queue and queue[0][0] <= until:
            t, _, kind, to, sender, msg = heapq.heappop(queue)
            self.now = t
            r = self.robots.get(to)
            if r is None or not r.alive:
                continue
            swim = r.swim
            if kind == _TICK:
                self._apply(to, swim.tick(t))
                self._at(t + swim.probe_timeout_s, _TIMEOUT, to)
                self._at(t + swim.period_s, _TICK, to)
            elif kind == _TIMEOUT:
                self._apply(to, swim.timeout(t))
            elif isinstance(msg, Heartbeat):
                if msg.robot == sender:
                    self._apply(to, swim.on_heartbeat(msg, t))
            elif isinstance(msg, ProbeRequest):
                self._apply(to, swim.on_probe_request(sender, msg, t))
            elif isinstance(msg, Vouch):
                self._apply(to, swim.on_vouch(sender, msg, t))
            elif isinstance(msg, Goodbye) and msg.robot == sender:
                self._apply(to, swim.on_goodbye(msg.robot, msg.incarnation))
        self.now = until

    def _apply(self, me: str, step: Step) -> None:
        for to, msg in step.sends:
            self.send(me, to, msg)
        for event, robot in step.events:
            self.events.append(Event(self.now, me, event, robot))

    # -- faults -------------------------------------------------------------------------
    def kill(self, name: str) -> None:
        """``name`` stops: it sends and answers nothing from now on."""
        self.robots[name].alive = False

    def lossy(self, a: str, b: str, loss: float) -> None:
        """Messages between ``a`` and ``b`` (both ways) are lost with this chance."""
        self.link_loss[(a, b)] = self.link_loss[(b, a)] = loss

    # -- reading ------------------------------------------------------------------------
    def failures(self) -> list[Event]:
        return [e for e in self.events if e.event is TeamEvent.FAILED]

    def members_of(self, name: str) -> frozenset[str]:
        return frozenset(self.robots[name].swim.members)

    def living(self) -> list[str]:
        return [n for n, r in self.robots.items() if r.alive]


_TICK, _TIMEOUT, _DELIVER = 0, 1, 2
