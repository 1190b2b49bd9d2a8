"""A lower bound on a scenario's mission time: no allocation, tree or timing can beat it.

It ignores auctions, ticks, messages, failures and the mission tree, and gives every
robot perfect knowledge; an operation takes its shortest draw (the simulation draws
durations within ``jitter`` of the model's: ``duration x (1 - jitter)``, so no draw
beats the bound); it is the largest of three:

- **chains**: each object's discovery -> identification -> carry, each step by the
  robot able to do it soonest. An object is discovered no earlier than an explorer
  arriving within its radius of it (its shortest path from the start to the nearest
  cell within that radius, at its speed, from when it is first present: see
  :func:`cover_times`) and exploring once; identified no earlier than that and
  than an identifier's drive from the start (path length) plus its duration; a
  contaminated one carried no earlier than that and than a decontaminator's drive there,
  then its operation and the carry to the decontamination area. The mission also ends
  no earlier than every reachable cell could have been explored.
- **work**: for every set of task kinds (explore, identify, decontaminate), the work
  only the robots able to do one of them can do, over their presence in time (joins,
  leaves, failures). A carry is the round trip from the decontamination area (where the
  previous carry ended; each robot's first one may start from the start cell) plus its
  operation; an identification its duration; exploring the reachable cells at the best
  duration per cell a robot's disc can cover. The identifiers also drive to every
  object they identify (the capability drives there first): together no less than a
  minimum spanning tree of the start and the objects under path lengths
  (:func:`visit_tree_m`), at the fastest identifier's speed; where the same robots
  carry, their drives count once, the longer of the two bounds.
- **carries after release**: for every time ``t``, the carries of objects that cannot
  be identified before ``t`` all happen after ``t`` (the scheduling bound for jobs with
  release times), each decontaminator's first one perhaps already driven to.

Computed in well under a second on the built-in caves (two distance fields and one pass
over the reachable cells).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from btcap.sim.mission.scenario import Event, Scenario
from btcap.sim.world.distance import Cell, distance_field, path_length
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel
from btcap.sim.world.store import MissionState

__all__ = ["Bound", "Presence", "cover_times", "mission_bound", "scenario_bound", "visit_tree_m"]

_KINDS = ("explore", "identify", "decontaminate")


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


@dataclass(frozen=True, slots=True)
class Bound:
    """The bound (seconds) and its three parts, to say which one binds."""

    seconds: float
    chains_s: float
    work_s: float
    release_s: float


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


def _finish(robots: Sequence[Presence], since: float, work: float) -> float:
    """The first time by which ``robots`` together could have done ``work`` seconds of
    it after ``since`` (inf if they are never present long enough)."""
    if work <= 0:
        return since
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


def _disc_cells(radius_cells: float) -> int:
    r = math.floor(radius_cells)
    d = np.arange(-r, r + 1)
    return int((d[:, None] ** 2 + d[None, :] ** 2 <= radius_cells**2).sum())


def _nearest_within(field: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
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


def cover_times(
    grid: GridMap,
    models: Sequence[RobotModel],
    present: Sequence[Presence] | None = None,
    jitter: float = 0.0,
) -> NDArray[np.float64]:
    """For every cell, the earliest time an exploration can have covered it (``inf``
    where none can): the soonest a robot able to explore, leaving the start when it is
    first present, drives to a cell within its radius of it, plus its exploration.

    A lower bound because an exploration covers the disc of its radius around the cell
    the robot stands on (:meth:`~btcap.sim.world.store.MissionState.explore`), and a robot
    reaches a cell no sooner than its shortest 4-connected path over free cells at its
    speed (the world moves it along such paths; :mod:`btcap.sim.world.distance`): the least
    path length over the disc around the covered cell. Never earlier than the straight
    line less the radius (a path is no shorter than the straight line).
    """
    present = list(present) if present is not None else [Presence()] * len(models)
    cs = grid.cell_size_m
    steps = distance_field(grid.free, grid.start)
    start_m = np.where(steps >= 0, steps * cs, math.inf)
    cover = np.full(grid.shape, math.inf)
    near: dict[float, NDArray[np.float64]] = {}  # radius -> metres to within it, by cell
    for i, m in enumerate(models):
        if not m.can("explore"):
            continue
        op = m.operation("explore")
        if op.radius_m not in near:
            near[op.radius_m] = _nearest_within(start_m, op.radius_m / cs)
        cover = np.minimum(
            cover,
            present[i].start + near[op.radius_m] / m.speed_mps + op.duration_s * (1 - jitter),
        )
    return cover


def visit_tree_m(grid: GridMap, cells: Sequence[Cell]) -> float:
    """Metres robots starting at ``grid.start`` drive, all together, to stand on every one
    of ``cells`` (reachable ones): no less than a minimum spanning tree of the start and
    the cells under path lengths. Each robot's drive, cut where it first reaches each
    cell, is a chain of drives between them, each no shorter than their path length; the
    chains of all robots join at the start and reach every cell, so together they are a
    spanning tree of those points, and none is shorter than the minimum one."""
    nodes = [grid.start, *dict.fromkeys(c for c in cells if c != grid.start)]
    n = len(nodes)
    if n < 2:
        return 0.0
    cs = grid.cell_size_m
    far = np.empty((n, n))
    for i, cell in enumerate(nodes):
        field = distance_field(grid.free, cell)
        far[i] = [path_length(field, other, cs) for other in nodes]
    joined = np.zeros(n, dtype=bool)
    joined[0] = True
    nearest = far[0].copy()
    total = 0.0
    for _ in range(n - 1):  # Prim's: the nearest point not yet joined, one at a time
        cand = np.where(joined, math.inf, nearest)
        j = int(np.argmin(cand))
        total += float(cand[j])
        joined[j] = True
        nearest = np.minimum(nearest, far[j])
    return total


def mission_bound(
    grid: GridMap,
    models: Sequence[RobotModel],
    objects: Sequence[tuple[Cell, bool]],
    present: Sequence[Presence] | None = None,
    jitter: float = 0.0,
) -> Bound:
    """The bound for robots ``models`` (all starting at ``grid.start``, present as
    ``present`` says: default, always) and ``objects`` (cell, contaminated), durations
    ``jitter`` shorter at most."""
    present = list(present) if present is not None else [Presence()] * len(models)
    cs = grid.cell_size_m
    from_start = distance_field(grid.free, grid.start)
    from_decon = distance_field(grid.free, grid.decon_area)
    able = {k: [i for i, m in enumerate(models) if m.can(k)] for k in _KINDS}

    def dur(i: int, k: str) -> float:
        return models[i].operation(k).duration_s * (1 - jitter)

    # -- chains ---------------------------------------------------------------------
    reach = np.argwhere(grid.reachable)
    cover = cover_times(grid, models, present, jitter)[reach[:, 0], reach[:, 1]]
    explored = float(cover.max()) if len(reach) else 0.0
    index = {(int(r), int(c)): j for j, (r, c) in enumerate(reach)}
    chains = explored
    release: list[tuple[float, float, float]] = []  # (identified by, work, approach) per dirty
    carry_work: list[float] = []
    first_saving: list[float] = []
    for cell, dirty in objects:
        found = float(cover[index[cell]]) if cell in index else math.inf
        drive = path_length(from_start, cell, cs)
        ident = (
            min(
                (max(found, present[i].start + drive / models[i].speed_mps) + dur(i, "identify"))
                for i in able["identify"]
            )
            if able["identify"]
            else math.inf
        )
        end = ident
        if dirty:
            back = path_length(from_decon, cell, cs)
            best = work = saving = approach = math.inf
            for i in able["decontaminate"]:
                v = models[i].speed_mps
                at = max(ident, present[i].start + drive / v)
                best = min(best, at + dur(i, "decontaminate") + back / v)
                work = min(work, 2 * back / v + dur(i, "decontaminate"))
                saving = min(saving, max(0.0, back - drive) / v)
                approach = min(approach, back / v)
            end = best
            carry_work.append(work)
            first_saving.append(saving)
            release.append((ident, work, approach))
        chains = max(chains, end)

    # -- work per set of kinds ----------------------------------------------------------
    n_cells = len(reach)
    id_work = [
        min((dur(i, "identify") for i in able["identify"]), default=math.inf) for _ in objects
    ]
    per_cell = min(
        (
            dur(i, "explore") / _disc_cells(models[i].operation("explore").radius_m / cs)
            for i in able["explore"]
        ),
        default=math.inf,
    )
    k_carry = len(able["decontaminate"])
    saved = sum(sorted(first_saving, reverse=True)[:k_carry])
    kind_work = {
        "explore": n_cells * per_cell if n_cells else 0.0,
        "identify": sum(id_work),
        "decontaminate": max(0.0, sum(carry_work) - saved),
    }
    # the identifiers' drives to every object they identify (carry_work has the carriers')
    seen = [cell for cell, _ in objects if cell in index]
    fastest = max((models[i].speed_mps for i in able["identify"]), default=1.0)
    visits = visit_tree_m(grid, seen) / fastest
    shared = bool(set(able["identify"]) & set(able["decontaminate"]))
    dec_ops = sum(
        min((dur(i, "decontaminate") for i in able["decontaminate"]), default=math.inf)
        for _, dirty in objects
        if dirty
    )
    work_s = 0.0
    for size in (1, 2, 3):
        for kinds in combinations(_KINDS, size):
            robots = sorted({i for k in kinds for i in able[k]})
            total = sum(kind_work[k] for k in kinds)
            if "identify" in kinds and "decontaminate" in kinds and shared:
                # the same robots drive for both: at least the longer of the two drives
                carry = max(kind_work["decontaminate"], dec_ops + visits)
                total += carry - kind_work["decontaminate"]
            elif "identify" in kinds:
                total += visits
            if total > 0:
                work_s = max(work_s, _finish([present[i] for i in robots], 0.0, total))

    # -- carries after their release ------------------------------------------------------
    release_s = 0.0
    carriers = [present[i] for i in able["decontaminate"]]
    for since, _, _ in release:
        later = [(w, a) for r, w, a in release if r >= since]
        driven = sorted((a for _, a in later), reverse=True)[:k_carry]  # perhaps before
        total = sum(w for w, _ in later) - sum(driven)
        release_s = max(release_s, _finish(carriers, since, total))
    seconds = max(chains, work_s, release_s)
    return Bound(round(seconds, 1), round(chains, 1), round(work_s, 1), round(release_s, 1))


def scenario_bound(s: Scenario) -> Bound:
    """The bound of scenario ``s`` with its objects as the runner scatters them."""
    grid = s.grid()
    state = MissionState.scatter(
        grid, s.objects, s.contaminated_share, np.random.default_rng(s.seed)
    )
    models = s.models()
    return mission_bound(
        grid,
        [models[r.model] for r in s.robots],
        [(o.cell, o.contaminated) for o in state.objects],
        presence([r.name for r in s.robots], s.events),
        s.sim.delay_jitter,
    )
