"""When each robot is in the team, and how soon robots present at times can do some work:
the time base of the mission-time bound (:mod:`btcap.sim.mission.bound`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from btcap.sim.mission.scenariofile import Event

__all__ = ["Presence", "finish", "presence"]


@dataclass(frozen=True, slots=True)
class Presence:
    """When a robot is in the team: from ``start`` to ``end``, less ``gaps`` (failures)."""

    start: float = 0.0
    end: float = math.inf
    gaps: tuple[tuple[float, float], ...] = ()

    def within(self, a: float, b: float) -> float:
        """Seconds present in [a, b]."""
        lo, hi = max(a, self.start), min(b, self.end)
        if hi <= lo:
            return 0.0
        lost = sum(max(0.0, min(hi, g1) - max(lo, g0)) for g0, g1 in self.gaps)
        return hi - lo - lost


def presence(robots: Sequence[str], events: Sequence[Event]) -> list[Presence]:
    """Each robot's presence from a scenario's events."""
    out = []
    for name in robots:
        mine = sorted((e for e in events if e.robot == name), key=lambda e: e.at)
        start = mine[0].at if mine and mine[0].kind == "join" else 0.0
        end = next((e.at for e in mine if e.kind == "leave"), math.inf)
        gaps = tuple((e.at, e.at + e.duration) for e in mine if e.kind == "fail")
        out.append(Presence(start, end, gaps))
    return out


def finish(robots: Sequence[Presence], since: float, work: float) -> float:
    """The first time by which ``robots`` together could have done ``work`` seconds of
    it after ``since`` (inf if they are never present long enough)."""
    if work <= 0:
        return since
    if math.isinf(since):  # (work after a time never reached: inf - inf looped for ever)
        return math.inf
    hi = since + work
    while sum(p.within(since, hi) for p in robots) < work:
        if hi - since > 1e7:
            return math.inf
        hi = since + 2 * (hi - since)
    lo = since
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if sum(p.within(since, mid) for p in robots) < work else (lo, mid)
    return hi
