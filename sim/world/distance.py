"""Shortest-path distances on an occupancy grid, computed as a vectorised wavefront.

Moves are 4-connected unit steps (N, S, W, E). That keeps distances integer, makes a
distance field the exact breadth-first-search answer (so it can be checked against a plain
BFS) and matches how a ground robot crawls through a cave corridor; a path length in metres
is the step count times the map's cell size.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "UNREACHABLE",
    "Cell",
    "CellLike",
    "DistanceCache",
    "as_cell",
    "distance_field",
    "path_length",
]

Cell: TypeAlias = tuple[int, int]
"""A grid cell as ``(row, col)``."""

CellLike: TypeAlias = Sequence[int] | NDArray[np.integer[Any]]
"""Anything with two integer entries ``(row, col)``: a tuple, a list or a numpy row."""

UNREACHABLE = -1
"""Distance-field value of a cell that cannot reach the goal (walls included)."""


def as_cell(cell: CellLike) -> Cell:
    """Normalise ``cell`` to a hashable ``(row, col)`` of Python ints (cache keys need it)."""
    values = [int(v) for v in cell]
    if len(values) != 2:
        raise ValueError(f"a cell is (row, col), got {cell!r}")
    return values[0], values[1]


def _check_free(free: NDArray[Any]) -> NDArray[np.bool_]:
    array = np.asarray(free)
    if array.ndim != 2 or array.dtype != np.bool_:
        raise ValueError(f"free must be a 2-D bool array, got {array.dtype} {array.shape}")
    return array


def distance_field(free: NDArray[np.bool_], goal: CellLike) -> NDArray[np.int32]:
    """Steps from every cell to ``goal`` (-1 where unreachable), one numpy pass per BFS level.

    The grid is padded with a wall border and flattened, so a neighbour is the frontier
    index plus a constant offset and no bounds checks are needed. Each level expands the
    whole frontier at once; duplicates (a cell reached from two parents) are dropped with
    an owner-array trick, which is cheaper than ``np.unique`` because it does not sort.
    """
    grid = _check_free(free)
    height, width = grid.shape
    row, col = as_cell(goal)
    if not (0 <= row < height and 0 <= col < width) or not grid[row, col]:
        raise ValueError(f"goal {(row, col)} is not a free cell of the {height}x{width} grid")
    padded_width = width + 2
    unvisited = np.zeros((height + 2, padded_width), dtype=np.bool_)
    unvisited[1:-1, 1:-1] = grid
    open_cells = unvisited.ravel()
    dist = np.full(open_cells.size, UNREACHABLE, dtype=np.int32)
    owner = np.empty(open_cells.size, dtype=np.intp)
    ranks = np.arange(open_cells.size, dtype=np.intp)
    offsets = np.array([-padded_width, padded_width, -1, 1], dtype=np.intp)

    frontier = np.array([(row + 1) * padded_width + col + 1], dtype=np.intp)
    open_cells[frontier] = False
    dist[frontier] = 0
    level = 0
    while frontier.size:
        level += 1
        reached = (frontier[:, None] + offsets).ravel()
        reached = reached[open_cells[reached]]
        rank = ranks[: reached.size]
        owner[reached] = rank
        reached = reached[owner[reached] == rank]
        open_cells[reached] = False
        dist[reached] = level
        frontier = reached
    return np.ascontiguousarray(dist.reshape(height + 2, padded_width)[1:-1, 1:-1])


def path_length(field: NDArray[np.int32], cell: CellLike, cell_size_m: float = 1.0) -> float:
    """Metres from ``cell`` to the field's goal; ``inf`` if unreachable, so it can be a bid."""
    row, col = as_cell(cell)
    height, width = field.shape
    if not (0 <= row < height and 0 <= col < width):
        raise ValueError(f"cell {(row, col)} is outside the {height}x{width} grid")
    steps = int(field[row, col])
    return math.inf if steps < 0 else steps * cell_size_m


class DistanceCache:
    """Bounded LRU of distance fields keyed by goal cell.

    Robots share few goals (objects, frontiers, the decontamination area), and bids ask
    for the same goals again and again, so a repeated goal should cost a dict lookup.
    Returned fields are read-only because they are shared.
    """

    def __init__(self, free: NDArray[np.bool_], maxsize: int = 256) -> None:
        if maxsize < 1:
            raise ValueError(f"maxsize must be >= 1, got {maxsize}")
        grid = _check_free(free).copy()
        grid.flags.writeable = False
        self._free = grid
        self._maxsize = maxsize
        self._fields: OrderedDict[Cell, NDArray[np.int32]] = OrderedDict()
        self.hits = 0
        self.misses = 0

    @property
    def free(self) -> NDArray[np.bool_]:
        """The (read-only) occupancy grid the fields are computed on."""
        return self._free

    @property
    def maxsize(self) -> int:
        return self._maxsize

    def __len__(self) -> int:
        return len(self._fields)

    def __contains__(self, goal: object) -> bool:
        return goal in self._fields

    def get(self, goal: CellLike) -> NDArray[np.int32]:
        """The distance field towards ``goal``; computed on a miss, evicting the oldest."""
        key = as_cell(goal)
        field = self._fields.get(key)
        if field is not None:
            self.hits += 1
            self._fields.move_to_end(key)
            return field
        self.misses += 1
        field = distance_field(self._free, key)
        field.flags.writeable = False
        self._fields[key] = field
        if len(self._fields) > self._maxsize:
            self._fields.popitem(last=False)
        return field

    def clear(self) -> None:
        """Forget every field (the counters keep counting)."""
        self._fields.clear()
