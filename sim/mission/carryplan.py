"""Which of the carries waiting the pool mission offers to the carriers free now.

Every carry waiting was auctioned at once, and the allocation gave a carrier that came
free the dearest one (the least total cost: the carry that waiting costs most), so the
longest went first; that is not the soonest end. Full-team-6 seed 1: carries of 198, 166
and 124 s left, one Husky free at 416 s and the other at 463 s; the longest first ended
at 739 s, the two shorter ones on the Husky free first at 707 s. :class:`CarryTurns`
plans the carries waiting on the carriers, each to the carrier free soonest, in the order
that ends them soonest (:func:`carry_plan`: every order of a few, the longest first
beyond), and offers only those the plan starts now; the others wait for their carrier.
Only carries known to be waiting are planned: one that comes later is planned then.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass

from btcap.sim.world.distance import Cell, distance_field, path_length
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel

__all__ = [
    "EXHAUSTIVE",
    "FROM_AREA_S",
    "CarryPace",
    "CarryTurns",
    "carrier_pace",
    "carry_metres",
    "carry_plan",
]

#: Up to this many carries, every order is tried; beyond, the longest first.
EXHAUSTIVE = 6
#: A carry that begins this soon after another ended starts at the decontamination area
#: (the carrier that came free there); one that begins otherwise, from standing by.
FROM_AREA_S = 3.0


@dataclass(frozen=True, slots=True)
class CarryPace:
    """How long a carrier takes for a carry of ``m`` metres (object to decontamination
    area): the drive out (all of it from the area) and back at ``speed_mps``, then
    ``op_s``."""

    speed_mps: float = 1.0
    op_s: float = 0.0

    def seconds(self, m: float, *, out: float = 1.0) -> float:
        """``out``: the part of the drive out still to drive (1: from the area)."""
        return (1.0 + out) * m / self.speed_mps + self.op_s


def carrier_pace(models: Sequence[RobotModel]) -> CarryPace | None:
    """The :class:`CarryPace` of the robots of ``models`` that carry (their mean); None
    if none does."""
    able = [m for m in models if m.can("decontaminate")]
    if not able:
        return None
    speed = sum(m.speed_mps for m in able) / len(able)
    op_s = sum(m.operation("decontaminate").duration_s for m in able) / len(able)
    return CarryPace(speed, op_s)


def carry_metres(grid: GridMap) -> Callable[[Cell], float]:
    """The path from a cell to the decontamination area of ``grid``, in metres."""
    field = distance_field(grid.free, grid.decon_area)
    return lambda cell: path_length(field, cell, grid.cell_size_m)


def _schedule(
    free_at: Sequence[float], order: Sequence[tuple[Hashable, float]]
) -> tuple[tuple[float, float], list[tuple[Hashable, int, float]]]:
    """Each carry of ``order`` in turn to the carrier free soonest (the lowest index on a
    tie): ((end, sum of ends), [(carry, carrier, start)])."""
    at = list(free_at)
    out: list[tuple[Hashable, int, float]] = []
    total = 0.0
    for key, s in order:
        k = min(range(len(at)), key=lambda j: (at[j], j))
        out.append((key, k, at[k]))
        at[k] += s
        total += at[k]
    return (max(at, default=0.0), total), out


def carry_plan(
    free_at: Sequence[float], carries: Sequence[tuple[Hashable, float]]
) -> list[tuple[Hashable, int, float]]:
    """``carries`` ``(key, seconds)`` on carriers free at ``free_at`` (clock seconds),
    each in turn to the carrier free soonest: of every order (up to :data:`EXHAUSTIVE`
    carries; beyond, the longest first only) the one that ends soonest, then with the
    least sum of ends, then the longest first; as ``(carry, carrier, start)``."""
    if not free_at:
        return []
    longest = sorted(carries, key=lambda c: -c[1])
    best = _schedule(free_at, longest)
    if len(carries) <= EXHAUSTIVE:
        for order in itertools.permutations(longest):
            got = _schedule(free_at, order)
            if got[0] < best[0]:
                best = got
    return best[1]


class CarryTurns:
    """The carries of one pool on its ``carriers`` (robots that only carry; the
    auction decides which robot): when each carry under way began, to tell when its
    carrier comes free, and which carries waiting to offer now."""

    __slots__ = ("_began", "_cache", "_freed_at", "carriers", "metres", "pace")

    def __init__(self, carriers: int, pace: CarryPace, metres: Callable[[Cell], float]) -> None:
        self.carriers, self.pace, self.metres = carriers, pace, metres
        self._began: dict[Hashable, tuple[float, bool]] = {}  # -> (when, from the area)
        self._freed_at = -math.inf  # when a carry last ended
        self._cache: tuple[object, set[Hashable]] | None = None

    def forget(self) -> None:
        """Start over (the pool was reset)."""
        self._began.clear()
        self._freed_at = -math.inf
        self._cache = None

    def _track(self, now: float, under_way: Mapping[Hashable, Cell]) -> None:
        if set(self._began) - set(under_way):  # a carry ended or failed: a carrier is free
            self._freed_at = now
            self._began = {k: v for k, v in self._began.items() if k in under_way}
        for k in under_way:
            if k not in self._began:
                self._began[k] = (now, now - self._freed_at <= FROM_AREA_S)

    def free_at(self, now: float, under_way: Mapping[Hashable, Cell]) -> list[float]:
        """When each carrier comes free, soonest first: now if it has no carry; else its
        carry's begin plus its seconds (half the drive out if it began from standing by:
        where the carrier stood is the auction's), but never now (it is not free yet)."""
        busy = []
        for k, cell in under_way.items():
            at, from_area = self._began.get(k, (now, True))
            secs = self.pace.seconds(self.metres(cell), out=1.0 if from_area else 0.5)
            busy.append(max(now + 1.0, at + secs))
        return sorted(busy + [now] * max(0, self.carriers - len(busy)))

    def offer(
        self, now: float, waiting: Mapping[Hashable, Cell], under_way: Mapping[Hashable, Cell]
    ) -> set[Hashable]:
        """Of the carries ``waiting`` (to begin; where their objects lie), those the
        plan starts now, given those ``under_way`` (a robot has them)."""
        self._track(now, under_way)
        if not waiting or len(under_way) >= self.carriers:
            return set()  # no carrier free now: the plan could start nothing
        free_at = self.free_at(now, under_way)
        carries = [(k, self.pace.seconds(self.metres(c))) for k, c in waiting.items()]
        key = (tuple(free_at), tuple(carries))
        if self._cache is None or self._cache[0] != key:
            plan = carry_plan(free_at, carries)
            self._cache = (key, {k for k, _, start in plan if start <= now})
        return self._cache[1]
