"""Robots driving on a grid map, stored column-wise so one step moves all of them at once.

For every goal a robot currently heads for, the world keeps two planes in a slab: the
distance field and a next-hop table (the offset of the first neighbour, in N, S, W, E
order, that is one step closer), both over the map padded with a wall border and
flattened. A robot's state is its index into that slab (goal plane + cell), so a move is
"add the next-hop offset" and needs no bounds checks. Plane 0 is a parking plane for idle
robots (no hops, an unreachable goal), which lets a step run over all robots without first
selecting the moving ones.
"""

from __future__ import annotations

import math
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from btcap.sim.world.distance import Cell, CellLike, DistanceCache, as_cell
from btcap.sim.world.grid import GridMap

__all__ = ["CACHE_SIZE", "World"]

#: Distance fields the world keeps by default (4 bytes a map cell each).
CACHE_SIZE = 256

_T = TypeVar("_T", bound=np.generic)
_PARKED = 0  # slab plane of idle robots: no hop anywhere, goal never reached
_NEVER = np.iinfo(np.int32).max
_INITIAL_CAPACITY = 16
_INITIAL_PLANES = 4
_ROBOT_COLUMNS = (
    ("_at", np.intp, 0),
    ("_slot", np.intp, _PARKED),
    ("_goal", np.intp, -1),
    ("_speed", np.float64, 0.0),
    ("_rate", np.float64, 0.0),
    ("_cost", np.float64, 0.0),
    ("_progress", np.float64, 0.0),
    ("_moved", np.int64, 0),
    ("_active", np.bool_, False),
    ("_moving", np.bool_, False),
)


class World:
    """A team of point robots on a :class:`GridMap`, moved along shortest 4-connected paths.

    Robots are addressed by the index :meth:`add_robot` returns; indices are never reused,
    so a robot that fails and comes back keeps its identity. Speeds are given in m/s and
    stored in cells/s; a robot accumulates fractional progress and moves whole cells.
    Each goal in use at once costs 6 bytes per map cell (distance + next hop); the slab
    grows to the largest number of distinct goals in use and reuses freed planes.
    """

    _at: NDArray[np.intp]  # slab index: plane * plane_size + padded flat cell
    _slot: NDArray[np.intp]  # plane of the robot's goal, _PARKED when idle
    _goal: NDArray[np.intp]  # padded flat goal cell, -1 if never given one
    _speed: NDArray[np.float64]  # cells/s
    _rate: NDArray[np.float64]  # cells/s while moving, 0 otherwise
    _cost: NDArray[np.float64]
    _progress: NDArray[np.float64]
    _moved: NDArray[np.int64]  # cells travelled
    _active: NDArray[np.bool_]
    _moving: NDArray[np.bool_]

    def __init__(
        self, grid: GridMap, *, cache: DistanceCache | None = None, cache_size: int = CACHE_SIZE
    ) -> None:
        if cache is None:
            cache = DistanceCache(grid.free, maxsize=cache_size)
        elif cache.free.shape != grid.free.shape or not np.array_equal(cache.free, grid.free):
            raise ValueError("the distance cache was built for a different map")
        self.grid = grid
        self.cache = cache
        height, width = grid.shape
        self._width_p = width + 2
        self._plane = (height + 2) * (width + 2)
        self._offsets = np.array([-self._width_p, self._width_p, -1, 1], dtype=np.intp)
        self._n = 0
        for name, dtype, fill in _ROBOT_COLUMNS:
            setattr(self, name, np.full(_INITIAL_CAPACITY, fill, dtype=dtype))
        # Hops are +-1 or +-padded width: int16 halves the slab's cache footprint.
        hop_type = np.int16 if self._width_p <= np.iinfo(np.int16).max else np.int32
        self._dist = np.zeros((_INITIAL_PLANES, self._plane), dtype=np.int32)
        self._dist[_PARKED] = _NEVER  # idle robots never "arrive"
        self._hop: NDArray[np.signedinteger[Any]] = np.zeros(
            (_INITIAL_PLANES, self._plane), dtype=hop_type
        )
        self._slot_of: dict[Cell, int] = {}
        self._slot_goal: list[Cell | None] = [None] * _INITIAL_PLANES
        self._slot_refs: list[int] = [0] * _INITIAL_PLANES
        self._free_slots = list(range(_INITIAL_PLANES - 1, _PARKED, -1))

    # -- robots -------------------------------------------------------------------------

    def __len__(self) -> int:
        return self._n

    def add_robot(self, cell: CellLike, *, speed_mps: float = 1.0, cost_factor: float = 1.0) -> int:
        """Place an active, idle robot on a free cell; returns its index."""
        row, col = as_cell(cell)
        if not self.grid.is_free((row, col)):
            raise ValueError(f"cannot place a robot on {(row, col)}: not a free cell")
        if not (math.isfinite(speed_mps) and speed_mps > 0):
            raise ValueError(f"speed must be a positive number of m/s, got {speed_mps}")
        if not (math.isfinite(cost_factor) and cost_factor >= 0):
            raise ValueError(f"cost factor must be finite and >= 0, got {cost_factor}")
        if self._n == len(self._at):
            self._grow_robots()
        i = self._n
        self._n += 1
        self._at[i] = self._flat(row, col)
        self._speed[i] = speed_mps / self.grid.cell_size_m
        self._cost[i] = cost_factor
        self._active[i] = True
        return i

    def set_goal(self, i: int, cell: CellLike) -> None:
        """Send robot ``i`` towards ``cell``; it is reported by :meth:`step` on arrival."""
        self._check_index(i)
        if not self._active[i]:
            raise ValueError(f"robot {i} is inactive")
        goal = as_cell(cell)
        if not self.grid.is_free(goal):
            raise ValueError(f"goal {goal} is not a free cell")
        cell_p = self._cell_p(i)
        slot = self._acquire(goal)
        if self._dist[slot, cell_p] < 0:
            self._release(slot)
            raise ValueError(f"goal {goal} is not reachable from robot {i} at {self.position(i)}")
        if self._moving[i]:
            self._release(int(self._slot[i]))
        self._goal[i] = self._flat(*goal)
        self._slot[i] = slot
        self._at[i] = slot * self._plane + cell_p
        self._rate[i] = self._speed[i]
        self._moving[i] = True

    def stop(self, i: int) -> None:
        """Cancel robot ``i``'s goal where it stands (e.g. its task was pre-empted)."""
        self._check_index(i)
        if self._moving[i]:
            self._park(i)

    def deactivate(self, i: int) -> None:
        """Take robot ``i`` out of the team (failure, leave): it stops and drops its goal."""
        self.stop(i)
        self._active[i] = False

    def activate(self, i: int) -> None:
        """Bring robot ``i`` back where it stopped, idle."""
        self._check_index(i)
        self._active[i] = True

    # -- state --------------------------------------------------------------------------

    @property
    def positions(self) -> NDArray[np.intp]:
        """``(n, 2)`` cells of all robots (a fresh array)."""
        n = self._n
        return self._cells_of(self._at[:n] - self._slot[:n] * self._plane)

    @property
    def goals(self) -> NDArray[np.intp]:
        """``(n, 2)`` last goal cell of each robot, ``(-1, -1)`` if it never had one."""
        goals = self._cells_of(self._goal[: self._n])
        goals[self._goal[: self._n] < 0] = -1
        return goals

    @property
    def active(self) -> NDArray[np.bool_]:
        return _read_only(self._active[: self._n])

    @property
    def moving(self) -> NDArray[np.bool_]:
        """Robots with a goal they have not reached yet."""
        return _read_only(self._moving[: self._n])

    @property
    def speed_cells_per_s(self) -> NDArray[np.float64]:
        return _read_only(self._speed[: self._n])

    @property
    def cost_factor(self) -> NDArray[np.float64]:
        return _read_only(self._cost[: self._n])

    @property
    def progress(self) -> NDArray[np.float64]:
        """Fraction of a cell each robot has covered towards its next move."""
        return _read_only(self._progress[: self._n])

    @property
    def travelled_m(self) -> NDArray[np.float64]:
        """Distance each robot has driven (a fresh array)."""
        travelled = self._moved[: self._n].astype(np.float64)
        travelled *= self.grid.cell_size_m
        return travelled

    def position(self, i: int) -> Cell:
        self._check_index(i)
        row, col = divmod(self._cell_p(i), self._width_p)
        return row - 1, col - 1

    # -- motion -------------------------------------------------------------------------

    def step(self, dt: float) -> NDArray[np.intp]:
        """Advance every moving robot by ``dt`` seconds; returns the (sorted) arrivals.

        Runs over all robots at once (idle ones sit on the parking plane at rate 0): one
        gather finds the remaining distances, then each sub-step (as many as the most
        cells any robot covers) moves everyone with cells left by one next-hop gather.
        """
        _check_dt(dt)
        n = self._n
        progress = self._progress[:n]
        progress += self._rate[:n] * dt
        whole = progress.astype(np.intp)
        progress -= whole
        at = self._at[:n]
        remaining = self._dist.ravel()[at]
        moves = np.minimum(whole, remaining)
        hop = self._hop.ravel()
        for sub in range(int(moves.max(initial=0))):
            at += hop[at] * (moves > sub)
        self._moved[:n] += moves
        arrived: NDArray[np.intp] = np.flatnonzero(remaining <= whole)
        if arrived.size:
            self._park_all(arrived)
        return arrived

    def step_loop(self, dt: float) -> NDArray[np.intp]:
        """Reference for :meth:`step`: the same update, one robot and one cell at a time.

        It scans neighbours instead of using the next-hop table, so tests comparing the
        two also check the table. The benchmark measures the speed-up against it.
        """
        _check_dt(dt)
        offsets = [int(o) for o in self._offsets]
        arrived: list[int] = []
        for i in range(self._n):
            if not self._moving[i]:
                continue
            progress = float(self._progress[i]) + float(self._speed[i]) * dt
            whole = int(progress)
            slot = int(self._slot[i])
            field = self._dist[slot]
            cell = int(self._at[i]) - slot * self._plane
            remaining = int(field[cell])
            moves = min(whole, remaining)
            for _ in range(moves):
                closer = remaining - 1
                for offset in offsets:
                    if field[cell + offset] == closer:
                        cell += offset
                        break
                remaining = closer
            self._at[i] = slot * self._plane + cell
            self._moved[i] += moves
            self._progress[i] = progress - whole
            if remaining == 0:
                self._park(i)
                arrived.append(i)
        return np.array(arrived, dtype=np.intp)

    # -- queries ------------------------------------------------------------------------

    def within_radius(self, i: int, radius_m: float, points_cells: ArrayLike) -> NDArray[np.bool_]:
        """Mask of the ``(k, 2)`` cells whose centres lie within ``radius_m`` of robot ``i``."""
        row, col = self.position(i)
        points = np.asarray(points_cells, dtype=np.int64).reshape(-1, 2)
        gap = np.hypot(points[:, 0] - row, points[:, 1] - col) * self.grid.cell_size_m
        return np.asarray(gap <= radius_m, dtype=np.bool_)

    def travel_cost(self, i: int, cell: CellLike) -> float:
        """Path length (m) from robot ``i`` to ``cell`` times its cost factor; inf if no path."""
        self._check_index(i)
        field = self._field_to(cell)
        steps = int(field[self.position(i)])
        if steps < 0:
            return math.inf
        return steps * self.grid.cell_size_m * float(self._cost[i])

    def travel_costs(self, cell: CellLike) -> NDArray[np.float64]:
        """:meth:`travel_cost` of every robot to one ``cell`` (one field, one gather)."""
        field = self._field_to(cell)
        rows, cols = self.positions.T
        steps = field[rows, cols].astype(np.float64)
        costs: NDArray[np.float64] = steps * self.grid.cell_size_m * self._cost[: self._n]
        costs[steps < 0] = math.inf
        return costs

    def copy(self) -> World:
        """An independent world on the same map, sharing the distance cache."""
        twin = object.__new__(World)
        twin.__dict__.update(self.__dict__)
        for name, _, _ in _ROBOT_COLUMNS:
            setattr(twin, name, getattr(self, name).copy())
        twin._dist = self._dist.copy()
        twin._hop = self._hop.copy()
        twin._slot_of = dict(self._slot_of)
        twin._slot_goal = list(self._slot_goal)
        twin._slot_refs = list(self._slot_refs)
        twin._free_slots = list(self._free_slots)
        return twin

    # -- internals ----------------------------------------------------------------------

    def _flat(self, row: int, col: int) -> int:
        return (row + 1) * self._width_p + col + 1

    def _cell_p(self, i: int) -> int:
        return int(self._at[i]) - int(self._slot[i]) * self._plane

    def _cells_of(self, flat: NDArray[np.intp]) -> NDArray[np.intp]:
        rows, cols = np.divmod(flat, self._width_p)
        return np.stack((rows - 1, cols - 1), axis=-1)

    def _check_index(self, i: int) -> None:
        if not 0 <= i < self._n:
            raise IndexError(f"no robot {i} (the world has {self._n})")

    def _field_to(self, cell: CellLike) -> NDArray[np.int32]:
        goal = as_cell(cell)
        if not self.grid.is_free(goal):
            raise ValueError(f"target {goal} is not a free cell")
        return self.cache.get(goal)

    def _park(self, i: int) -> None:
        """Make robot ``i`` idle: parking plane, no rate, no partial cell."""
        self._park_all(np.array([i], dtype=np.intp))

    def _park_all(self, robots: NDArray[np.intp]) -> None:
        slots = self._slot[robots]
        self._at[robots] -= slots * self._plane
        self._slot[robots] = _PARKED
        self._rate[robots] = 0.0
        self._progress[robots] = 0.0
        self._moving[robots] = False
        for slot in slots.tolist():
            self._release(slot)

    def _acquire(self, goal: Cell) -> int:
        """Pin ``goal``'s planes in the slab (computing them on first use)."""
        slot = self._slot_of.get(goal)
        if slot is not None:
            self._slot_refs[slot] += 1
            return slot
        if not self._free_slots:
            self._grow_slab()
        slot = self._free_slots.pop()
        dist = self._dist[slot].reshape(self.grid.height + 2, self._width_p)
        dist.fill(-1)
        dist[1:-1, 1:-1] = self.cache.get(goal)
        self._hop[slot] = _next_hops(self._dist[slot], self._offsets)
        self._slot_of[goal] = slot
        self._slot_goal[slot] = goal
        self._slot_refs[slot] = 1
        return slot

    def _release(self, slot: int) -> None:
        self._slot_refs[slot] -= 1
        if self._slot_refs[slot] == 0:
            goal = self._slot_goal[slot]
            assert goal is not None
            del self._slot_of[goal]
            self._slot_goal[slot] = None
            self._free_slots.append(slot)

    def _grow_robots(self) -> None:
        extra = len(self._at)
        for name, dtype, fill in _ROBOT_COLUMNS:
            grown = np.concatenate((getattr(self, name), np.full(extra, fill, dtype=dtype)))
            setattr(self, name, grown)

    def _grow_slab(self) -> None:
        old = len(self._dist)
        self._dist = np.concatenate((self._dist, np.zeros_like(self._dist)))
        self._hop = np.concatenate((self._hop, np.zeros_like(self._hop)))
        self._slot_goal.extend([None] * old)
        self._slot_refs.extend([0] * old)
        self._free_slots.extend(range(2 * old - 1, old - 1, -1))


def _next_hops(dist: NDArray[np.int32], offsets: NDArray[np.intp]) -> NDArray[np.intp]:
    """Per padded cell, the offset of the first neighbour one step closer (0 at the goal)."""
    hops = np.zeros(dist.shape, dtype=np.intp)
    cells = np.flatnonzero(dist > 0)
    closer = dist[cells[:, None] + offsets] == (dist[cells] - 1)[:, None]
    hops[cells] = offsets[np.argmax(closer, axis=1)]
    return hops


def _read_only(array: NDArray[_T]) -> NDArray[_T]:
    view = array.view()
    view.flags.writeable = False
    return view


def _check_dt(dt: float) -> None:
    if not (math.isfinite(dt) and dt >= 0):
        raise ValueError(f"dt must be a finite number of seconds >= 0, got {dt}")
