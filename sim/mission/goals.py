"""Which exploration goal a free explore lane of the pool mission takes next.

The store lists goals oldest first: taken in that order, an explorer sweeps the cave
breadth first, flying back and forth between branches of the frontier (a Bebop spent
twice as long flying as exploring), and the last objects are found late. A
:class:`GoalPool` gives a free lane the goal nearest (path length) to where its last goal
left the explorer, after a fresh list (one asked for after that exploration ended, which
lists the goals it added beside it and not those it covered), and puts last the goals
near one another lane explores now (that exploration may cover them).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from btcap import ParallelForEach, Port, State
from btcap.sim.world.distance import Cell, DistanceCache
from btcap.sim.world.grid import GridMap

__all__ = ["GoalPool"]


class GoalPool(ParallelForEach):
    """A :class:`~btcap.bt.foreach.ParallelForEach` over goals ``(id, row, col)`` that
    chooses which goal a free lane takes (:meth:`order`).

    A lane that ended waits for a list asked for after it ended (input ``listed_at``, the
    clock time its list was asked for); then it takes the listed goal nearest to the
    goal it explored last (the start before its first), by path on ``grid`` (straight
    line without one), goals within ``near_m`` of a goal another lane explores now
    coming after all others. Free lanes are filled lowest first, so each is given the
    best goal for where it left its explorer, in turn."""

    __slots__ = ("_at", "_cache", "_ended_at", "_grid", "_near_m")
    INPUTS: ClassVar[Any] = {
        **ParallelForEach.INPUTS,
        "listed_at": Port(float, math.inf, "clock time the list was asked for"),
    }

    def __init__(
        self, *args: Any, grid: GridMap | None = None, near_m: float = 0.0, **kwargs: Any
    ) -> None:
        super().__init__(*args, **kwargs)
        self._grid = grid
        self._near_m = near_m
        self._cache = DistanceCache(grid.free, maxsize=16) if grid is not None else None
        self._at: dict[int, Cell] = {}  # lane -> the goal it explored last
        self._ended_at: dict[int, float] = {}  # lane -> when that lane's goal ended

    def _ended(self, i: int, s: State) -> bool:
        value = self._values[i]
        if not super()._ended(i, s):
            return False
        if value is not None:
            self._at[i] = (int(value[1]), int(value[2]))
            self._ended_at[i] = self.clock.now()
        return True

    def order(self, items: list[Any]) -> list[Any]:
        """The goals in the order the free lanes (lowest first) should take them; none
        while a free lane's last goal ended after the list was asked for."""
        listed_at = self.inputs["listed_at"]
        free = [i for i, k in enumerate(self._lanes) if k is None]
        if any(self._ended_at.get(i, -math.inf) >= listed_at for i in free):
            return [it for it in items if self._key(it) in self._lanes]  # wait: only running
        busy = {k for k in self._lanes if k is not None}
        skip = busy | self._finished | self._lost | set(self._retry_at)
        waiting = [it for it in items if self._key(it) not in skip]
        exploring = [
            (int(v[1]), int(v[2]))
            for k, v in zip(self._lanes, self._values, strict=True)
            if k is not None
        ]
        start = self._grid.start if self._grid is not None else None
        out: list[Any] = []
        for i in free:
            if not waiting:
                break
            best = min(
                range(len(waiting)),
                key=lambda j: self._score(self._at.get(i, start), waiting[j], exploring),
            )
            item = waiting.pop(best)
            out.append(item)
            exploring.append((int(item[1]), int(item[2])))
        return [*out, *waiting]

    def _score(self, at: Cell | None, item: Any, exploring: list[Cell]) -> tuple[bool, float]:
        cell = (int(item[1]), int(item[2]))
        near = self._near_m
        crowded = near > 0 and any(_metres(self._grid, cell, e) <= near for e in exploring)
        if at is None:
            return crowded, 0.0  # the list's order
        return crowded, self._path_m(at, cell)

    def _path_m(self, a: Cell, b: Cell) -> float:
        if self._cache is None or self._grid is None:
            return float(math.dist(a, b))
        steps = int(self._cache.get(a)[b])
        return steps * self._grid.cell_size_m if steps >= 0 else math.inf

    def on_reset(self) -> None:
        super().on_reset()
        self._at.clear()
        self._ended_at.clear()


def _metres(grid: GridMap | None, a: Cell, b: Cell) -> float:
    """Straight-line metres between two cells (a disc's reach ignores walls)."""
    size = grid.cell_size_m if grid is not None else 1.0
    return float(np.hypot(a[0] - b[0], a[1] - b[1])) * size
