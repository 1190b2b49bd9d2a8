"""Heartbeats that scale: whom to beat to, what to tell them, whom to ask about.

All-to-all heartbeats cost every robot a message per teammate per period. Past
``fanout`` peers a robot beats directly to ``fanout`` of them per period, in turns
through a shuffled order (so each peer still hears from it every
``ceil(peers / fanout)`` periods), and each heartbeat carries what its sender heard of
up to ``digest`` teammates, in turns too. A robot's latest beat then spreads like a
rumour, so liveness stays fresh with a constant number of messages of constant size per
robot and period: traffic per robot does not grow with the team.
"""

from __future__ import annotations

import math
import random
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

__all__ = ["Beat", "BeatPlan", "Introductions", "Turns", "detection_periods"]


class Turns:
    """Round-robin over a changing set of names, in an order shuffled each round."""

    def __init__(self, rng: random.Random) -> None:
        self._rng = rng
        self._queue: list[str] = []

    def take(self, names: Iterable[str], n: int) -> list[str]:
        """The next ``n`` of ``names`` (all of them when there are at most ``n``)."""
        pool = set(names)
        if len(pool) <= n:
            self._queue.clear()
            return sorted(pool)
        out: list[str] = []
        while len(out) < n:
            if not self._queue:
                self._queue = sorted(pool - set(out))
                self._rng.shuffle(self._queue)
            name = self._queue.pop()
            if name in pool and name not in out:
                out.append(name)
        return out


class Introductions:
    """Who is worth asking about a robot that teammates mention but we cannot reach.

    At most one request per robot per ``interval_s``; at most ``limit`` robots remembered
    (a teammate listing invented robots costs a bounded table, oldest forgotten first).
    """

    def __init__(self, interval_s: float, limit: int = 1024) -> None:
        self.interval_s = interval_s
        self.limit = limit
        self._asked: dict[str, float] = {}

    def due(self, robots: Sequence[str], now: float) -> list[str]:
        """The robots of ``robots`` to ask about now (each then counts as asked)."""
        out = []
        for robot in robots:
            last = self._asked.get(robot)
            if last is not None and now - last < self.interval_s:
                continue
            self._asked.pop(robot, None)
            self._asked[robot] = now
            out.append(robot)
        while len(self._asked) > self.limit:
            del self._asked[next(iter(self._asked))]
        return out

    def __len__(self) -> int:
        return len(self._asked)


def detection_periods(team: int, fanout: int) -> int:
    """Heartbeat periods a failure timeout should span for a team of ``team`` robots.

    Direct beats reach each peer every ``ceil((team - 1) / fanout)`` periods; hearsay
    usually brings a fresher beat within about ``log_fanout(team)`` periods. Twice that,
    plus two periods of slack, keeps false failures rare.
    """
    peers = max(team - 1, 1)
    if peers <= fanout:
        return 3
    spread = math.log(team) / math.log(max(fanout, 2))
    return math.ceil(2 * spread) + 2


@dataclass(frozen=True, slots=True)
class Beat:
    """Where one periodic heartbeat goes: every peer, or ``to``; with hearsay or not."""

    everyone: bool
    to: tuple[str, ...] = ()
    heard: bool = False


class BeatPlan:
    """Whom each periodic heartbeat goes to.

    Members come first: past ``fanout`` of them, ``fanout`` per period in turns (with
    hearsay). Peers that are not members (a seed not met yet, a robot back from a
    partition; or made-up ids an attacker announced) get ``fanout`` more per period in
    turns of their own, so however many there are they never crowd out the members.
    """

    def __init__(self, fanout: int, rng: random.Random) -> None:
        self.fanout = fanout
        self._members = Turns(rng)
        self._others = Turns(rng)

    def next(self, members: Iterable[str], peers: Iterable[str]) -> Beat:
        team, reachable = set(members), set(peers)
        if len(reachable) <= self.fanout:
            return Beat(everyone=True)
        others = reachable - team
        mine = self._members.take(team & reachable, self.fanout)
        rest = self._others.take(others, self.fanout) if others else []
        return Beat(False, tuple(mine + rest), heard=len(team) > self.fanout)
