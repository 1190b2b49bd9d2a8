"""How far robots must drive, all together, to reach a set of cells: the driving part of
the mission-time bound (:mod:`btcap.sim.mission.bound`), under shortest path lengths."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from btcap.sim.world.distance import Cell, distance_field, path_length
from btcap.sim.world.grid import GridMap

__all__ = ["Legs", "pieces_m", "visit_tree_m"]


class Legs:
    """Path lengths (metres) between the start (0), the decontamination area (1) and
    ``cells`` (2, 3, ...), one distance field each."""

    def __init__(self, grid: GridMap, cells: Sequence[Cell]) -> None:
        nodes = [grid.start, grid.decon_area, *cells]
        cs = grid.cell_size_m
        fields: dict[Cell, NDArray[np.int32]] = {}
        self.m = np.empty((len(nodes), len(nodes)))
        for i, cell in enumerate(nodes):
            if cell not in fields:
                fields[cell] = distance_field(grid.free, cell)
            self.m[i] = [path_length(fields[cell], other, cs) for other in nodes]


def _mst_edges(m: NDArray[np.float64]) -> list[float]:
    """The edges of a minimum spanning tree of the points of distance matrix ``m``."""
    n = len(m)
    if n < 2:
        return []
    joined = np.zeros(n, dtype=bool)
    joined[0] = True
    nearest = m[0].copy()
    edges = []
    for _ in range(n - 1):  # Prim's: the nearest point not yet joined, one at a time
        cand = np.where(joined, math.inf, nearest)
        j = int(np.argmin(cand))
        edges.append(float(cand[j]))
        joined[j] = True
        nearest = np.minimum(nearest, m[j])
    return edges


def visit_tree_m(grid: GridMap, cells: Sequence[Cell]) -> float:
    """Metres robots starting at ``grid.start`` drive, all together, to stand on every one
    of ``cells`` (reachable ones): no less than a minimum spanning tree of the start and
    the cells under path lengths. Each robot's drive, cut where it first reaches each
    cell, is a chain of drives between them, each no shorter than their path length; the
    chains of all robots join at the start and reach every cell, so together they are a
    spanning tree of those points, and none is shorter than the minimum one."""
    others = list(dict.fromkeys(c for c in cells if c != grid.start))
    legs = Legs(grid, others)
    keep = [0, *range(2, 2 + len(others))]
    return sum(_mst_edges(legs.m[np.ix_(keep, keep)]))


def pieces_m(
    legs: Legs,
    clean: Sequence[int],
    dirty: Sequence[int],
    robots: int,
    *,
    anywhere: bool,
    reach_m: float | Sequence[float] = math.inf,
) -> float:
    """Metres robots that carry (and perhaps identify) drive to stand on every one of
    ``clean`` and ``dirty`` (indices into ``legs``), besides the carries themselves
    (each dirty point on to the decontamination area).

    Cut a robot's drive at every point it must stand on and at every carry: each piece
    leads to a point from where the robot was, its start (``robots`` pieces at most: the
    start, or ``anywhere`` they stand, at no cost, or at the path from the start less
    ``reach_m`` if they stand no farther than that from it), the decontamination area
    (only after a carry: as many as dirty points) or a clean point (a dirty one is left
    by its carry).
    Dropping the other stops of a drive makes it no longer, so each point's piece is no
    shorter than the path from its predecessor: together no less than the cheapest
    choice of a predecessor for every point, each clean point and each start used once,
    the decontamination area once a dirty point (an assignment problem). A carry handed
    on (the carrier fails or is stopped and drops the object, another takes it on)
    changes nothing: swapping the two robots' drives from the handover on gives drives
    no longer in all, in which one robot carries the object all the way.
    """
    points = [*clean, *dirty]
    if not points:
        return 0.0
    starts = [0] * robots + [1] * len(dirty) + list(clean)
    cost = legs.m[np.ix_(starts, points)].T.copy()  # rows: points, columns: predecessors
    if anywhere:  # no farther from the start than ``reach_m`` (one for all, or each its own)
        first = cost[:, :robots]
        limit = np.broadcast_to(np.asarray(reach_m, dtype=float), (robots,))[None, :]
        near = np.isfinite(first) & (first > limit)
        cost[:, :robots] = np.where(near, first - limit, 0.0)
    for r in range(len(clean)):  # no point is its own predecessor
        cost[r, robots + len(dirty) + r] = math.inf
    big = 1e12
    cost = np.where(np.isfinite(cost), cost, big)
    rows, cols = linear_sum_assignment(cost)
    total = float(cost[rows, cols].sum())
    return total if total < big else math.inf
