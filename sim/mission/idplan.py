"""The pool mission's identification plan: one ranking of the objects awaiting
identification that both the identification turns and the carriers standing by read.

Taking objects oldest-found first drove full-team's one Spot back and forth across the
cave (seed 9: 842 m), and a carrier standing by at the oldest object waited where the
Spot was not going. The plan instead routes the identifiers: each object, in turn, goes
to the identifier that can be there soonest (its drive from where it stands or will
stand, priced in seconds at its speed, after the identifications planned for it before),
nearest first, so with one identifier it is a nearest-neighbour tour from where it is,
and with more each takes the objects near it. An object that has waited ``cap_s`` goes
before the others (oldest first), so none starves at the far end of the cave; not where
the identifiers also carry (:func:`identifier_pace`): there every object waits on them,
and the cap made the plan oldest-first for nearly all.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import Any

from btcap.sim.world.model import RobotModel

__all__ = ["CAP_S", "Identifier", "Pace", "Turns", "Waiting", "identifier_pace", "plan"]

#: Seconds an object waits before it goes first, where the identifiers do not carry.
CAP_S = 240.0

Cell = tuple[int, int]


@dataclass(slots=True)
class Identifier:
    """One identification at once, as the mission tree sees it (not a named robot: the
    auction decides who): where its robot stands, or will once the identification it
    is ``busy`` with ends (``None``: not known yet, before its first one)."""

    cell: Cell | None = None
    busy: Hashable | None = None


@dataclass(frozen=True, slots=True)
class Waiting:
    """An object awaiting identification, where it lies and how long it has waited."""

    key: Hashable
    cell: Cell
    waited_s: float


def plan(
    robots: Sequence[Identifier],
    waiting: Sequence[Waiting],
    *,
    speed: float,
    op_s: float,
    cap_s: float,
) -> list[tuple[Hashable, int]]:
    """The order ``waiting`` (oldest first) is identified in, each with the index of the
    identifier planned for it: first those that waited ``cap_s`` or more (oldest first),
    then, one at a time, the object an identifier can reach soonest (``speed`` cells per
    second, ``op_s`` seconds an identification; ties to the older object). An identifier
    whose cell is not known reaches every object at once: it takes the oldest."""
    if not robots:
        return [(w.key, -1) for w in waiting]
    at = [r.cell for r in robots]
    ready = [0.0 if r.busy is None else op_s for r in robots]  # busy: still identifying
    left = list(waiting)
    out: list[tuple[Hashable, int]] = []

    def reach(k: int, w: Waiting) -> float:
        here = at[k]
        return ready[k] + (0.0 if here is None else math.dist(here, w.cell) / speed)

    def take(k: int, w: Waiting) -> None:
        ready[k] = reach(k, w) + op_s
        at[k] = w.cell
        left.remove(w)
        out.append((w.key, k))

    ks = range(len(robots))
    for w in [w for w in waiting if w.waited_s >= cap_s]:
        take(min(ks, key=lambda k: reach(k, w)), w)
    while left:
        best = min(((reach(k, w), n, k) for n, w in enumerate(left) for k in ks))
        take(best[2], left[best[1]])
    return out


@dataclass(frozen=True, slots=True)
class Pace:
    """How the plan prices an identifier's work: ``speed`` cells per second driven,
    ``op_s`` seconds an identification, ``cap_s`` the wait after which an object goes
    before nearer ones, and whether the identifiers also ``carry`` (then one that found
    its object contaminated is not free until the carry's auction is over: it is the
    nearest bidder, and a turn opened meanwhile took it away from the carry)."""

    speed: float = 1.0
    op_s: float = 0.0
    cap_s: float = CAP_S
    carry: bool = False

    def options(self) -> dict[str, float | bool]:
        """As the :class:`~btcap.sim.mission.pool.ObjectPool`'s options."""
        return {
            "identify_speed": self.speed,
            "identify_s": self.op_s,
            "identify_wait_s": self.cap_s,
            "identify_carries": self.carry,
        }


def identifier_pace(models: Sequence[RobotModel], cell_size_m: float) -> Pace:
    """The :class:`Pace` of the robots that take the identifications: of ``models``, those
    quickest to identify (a Spot beside a Husky; the mean if several models tie).

    Where they also carry (Huskies: 60 s an identification, then the carry), no object
    goes first for having waited: the identifiers are the mission's bottleneck, nearly
    every object waits longer than :data:`CAP_S` for them, and the cap then ordered them
    all oldest-found first, which ignores where the identifiers stand (a Husky drove
    across the cave to the oldest object and back; huskies-bebop-joins, pool, time /
    bound: seeds 1-12 1.430 -> 1.401, seeds 13-24 1.384 -> 1.351). A finite number of
    objects bounds how long one waits anyway."""
    able = [m for m in models if m.identify is not None]
    if not able:
        return Pace()
    quickest = min(m.operation("identify").duration_s for m in able)
    own = [m for m in able if m.operation("identify").duration_s == quickest]
    mps = sum(m.speed_mps for m in own) / len(own)
    carry = all(m.can("decontaminate") for m in own)
    return Pace(mps / cell_size_m, quickest, math.inf if carry else CAP_S, carry=carry)


class Turns:
    """The identifiers of one pool (``most`` identifications at once), where they stand,
    and the plan of the objects awaiting identification, whose first object for each
    free identifier may start now."""

    __slots__ = ("_cache", "robots", "since")

    def __init__(self) -> None:
        self.robots: list[Identifier] = []
        self.since: dict[Hashable, float] = {}  # object -> when first listed to identify
        self._cache: tuple[Any, list[tuple[Hashable, int]]] | None = None

    def listed(self, keys: Sequence[Hashable], now: float) -> None:
        """The objects awaiting identification now (remembering since when)."""
        self.since = {k: self.since.get(k, now) for k in keys}

    def plan(
        self, most: int, awaiting: Sequence[tuple[Hashable, Cell]], now: float, pace: Pace
    ) -> list[tuple[Hashable, int]]:
        """:func:`plan` of ``awaiting``, oldest listed first (computed again only when
        they, the identifiers or the clock changed)."""
        rank = {k: n for n, k in enumerate(self.since)}  # in the list's order
        awaiting = sorted(awaiting, key=lambda a: rank.get(a[0], len(rank)))
        while len(self.robots) < most:
            self.robots.append(Identifier())
        key = (now, tuple(awaiting), tuple((r.cell, r.busy) for r in self.robots), pace)
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        waits = [Waiting(k, c, now - self.since.get(k, now)) for k, c in awaiting]
        order = plan(self.robots, waits, speed=pace.speed, op_s=pace.op_s, cap_s=pace.cap_s)
        self._cache = (key, order)
        return order

    def may_start(self, key: Hashable, order: Sequence[tuple[Hashable, int]]) -> bool:
        """Whether ``key`` is the first object ``order`` plans for a free identifier."""
        free = {k for k, r in enumerate(self.robots) if r.busy is None}
        for planned, k in order:
            if k in free:
                if planned == key:
                    return True
                free.discard(k)
        return False

    def started(self, key: Hashable, cell: Cell, order: Sequence[tuple[Hashable, int]]) -> None:
        """The identification of ``key`` at ``cell`` began: the identifier planned for it
        (or the free one nearest) is now bound there."""
        free = [k for k, r in enumerate(self.robots) if r.busy is None]
        if not free:
            return
        k = dict(order).get(key, -1)
        if k not in free:
            k = min(free, key=lambda f: _far(self.robots[f].cell, cell))
        self.robots[k].cell, self.robots[k].busy = cell, key

    def free(self, key: Hashable) -> None:
        """The identification of ``key`` ended: its identifier is free, standing there."""
        self.ended(set(r.busy for r in self.robots if r.busy != key))

    def ended(self, under_way: set[Hashable]) -> None:
        """Identifiers whose object is no longer ``under_way`` are free again (its
        identification ended, failed or was reset), standing where it was."""
        for r in self.robots:
            if r.busy is not None and r.busy not in under_way:
                r.busy = None

    def order(self, planned: Sequence[tuple[Hashable, int]]) -> list[Hashable]:
        """The objects under way, then those ``planned``, in order."""
        busy = [r.busy for r in self.robots if r.busy is not None]
        return list(dict.fromkeys(busy + [k for k, _ in planned]))


def _far(a: Cell | None, b: Cell) -> float:
    return 0.0 if a is None else math.dist(a, b)
