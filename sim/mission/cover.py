"""When each cell can have been explored at the earliest: the exploration part of the
mission-time bound (:mod:`btcap.sim.mission.bound`).

The store hands out exploration goals only as exploration goes on: the start first, then
cells on the frontier an exploration leaves (:meth:`~btcap.sim.world.store.MissionState.explore`),
and a robot explores where its goal is. So a far cell is not reached by one flight and one
exploration, but by a chain of explorations, each at a goal next to a cell an earlier one
covered (:func:`cover_times`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from btcap.sim.mission.presence import Presence
from btcap.sim.world.distance import distance_field
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel

__all__ = ["apart", "cover_times", "nearest_within"]

#: Rounds of :func:`cover_times` at most (each lengthens the chains by one exploration).
_MAX_ROUNDS = 10_000


def nearest_within(field: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
    """For every cell, the least ``field`` value over the cells within ``radius`` (cells,
    Euclidean, as an exploration's disc reaches): a min filter with a disc footprint, one
    row offset at a time over a sparse table of horizontal minima."""
    h, w = field.shape
    r = max(0, math.floor(radius))
    pad = np.full((h + 2 * r, w + 2 * r), math.inf)
    pad[r : r + h, r : r + w] = field
    table = [pad]  # table[k][y, x]: the least of pad[y, x : x + 2**k]
    while 2 ** len(table) <= 2 * r + 1:
        prev, step = table[-1], 2 ** (len(table) - 1)
        nxt = prev.copy()
        nxt[:, :-step] = np.minimum(prev[:, :-step], prev[:, step:])
        table.append(nxt)
    out = np.full((h, w), math.inf)
    for dy in range(-r, r + 1):
        half = math.floor(math.sqrt(max(0.0, radius * radius - dy * dy)) + 1e-9)
        k = (2 * half + 1).bit_length() - 1
        rows = table[k][r + dy : r + dy + h]
        left = rows[:, r - half : r - half + w]
        start = r + half - 2**k + 1
        right = rows[:, start : start + w]
        out = np.minimum(out, np.minimum(left, right))
    return out


def _beside(cover: NDArray[np.float64]) -> NDArray[np.float64]:
    """For every cell, the least value of its four neighbours."""
    out = np.full(cover.shape, math.inf)
    out[1:, :] = np.minimum(out[1:, :], cover[:-1, :])
    out[:-1, :] = np.minimum(out[:-1, :], cover[1:, :])
    out[:, 1:] = np.minimum(out[:, 1:], cover[:, :-1])
    out[:, :-1] = np.minimum(out[:, :-1], cover[:, 1:])
    return out


def cover_times(
    grid: GridMap,
    models: Sequence[RobotModel],
    present: Sequence[Presence] | None = None,
    jitter: float = 0.0,
) -> NDArray[np.float64]:
    """For every cell, the earliest time an exploration can have covered it (``inf``
    where none can).

    Why no run covers a cell sooner: an exploration covers the disc of its radius around
    the cell the robot stands on, when it ends, and a robot explores only at a goal the
    store handed out (the mission's Explore drives to the goal first). The first goal is
    the start; every other one is a frontier cell when an exploration adds it: a cell
    beside a covered one, so it exists no sooner than its neighbour's cover time. An
    exploration at cell ``g`` thus ends no sooner than the later of the goal's existence
    and an explorer's arrival (leaving the start when first present, its shortest path at
    its speed), plus its shortest duration; and a cell is covered no sooner than the
    earliest exploration ending within its radius. Computed as a fixpoint, each round one
    exploration longer in the chains, from the start's only.
    """
    present = list(present) if present is not None else [Presence()] * len(models)
    cs = grid.cell_size_m
    reach = grid.reachable
    steps = distance_field(grid.free, grid.start)
    start_m = np.where((steps >= 0) & reach, steps * cs, math.inf)
    kinds: dict[tuple[float, float, float], float] = {}  # (speed, radius, duration) -> from
    for i, m in enumerate(models):
        if m.can("explore"):
            op = m.operation("explore")
            key = (m.speed_mps, op.radius_m / cs, op.duration_s * (1 - jitter))
            kinds[key] = min(kinds.get(key, math.inf), present[i].start)
    if not kinds:
        return np.full(grid.shape, math.inf)
    arrive = {k: t0 + start_m / k[0] for k, t0 in kinds.items()}
    ends = {}  # kind -> the earliest end of an exploration by it at each cell
    for k in kinds:
        e = np.full(grid.shape, math.inf)
        e[grid.start] = arrive[k][grid.start] + k[2]
        ends[k] = e
    cover = np.full(grid.shape, math.inf)
    for _ in range(_MAX_ROUNDS):
        cover = np.full(grid.shape, math.inf)
        for k, e in ends.items():
            cover = np.minimum(cover, nearest_within(e, k[1]))
        cover[~reach] = math.inf  # an exploration covers reachable cells only
        goal = _beside(cover)
        goal[grid.start] = 0.0
        changed = False
        for k, e in ends.items():
            new = np.minimum(e, np.maximum(goal, arrive[k]) + k[2])
            if not np.array_equal(new, e):
                changed = True
                ends[k] = new
        if not changed:
            break
    return cover


def apart(grid: GridMap, radius_cells: float) -> int:
    """How many explorations of discs of ``radius_cells`` at most, at the least, cover
    every reachable cell: the size of a set of reachable cells farther than twice that
    apart (in reading order, each the first not yet too near one taken). A disc holds
    no two cells farther apart than its diameter, so each such cell needs an exploration
    of its own, whatever the order, robots or goals."""
    cells = np.argwhere(grid.reachable)
    left = np.ones(len(cells), dtype=bool)
    far = (2 * radius_cells) ** 2
    count = 0
    while left.any():
        first = cells[int(np.argmax(left))]
        count += 1
        left &= ((cells - first) ** 2).sum(axis=1) > far
    return count
