"""A lower bound on a scenario's mission time: no allocation, tree or timing can beat it.

It ignores auctions, ticks, messages, failures and the mission tree, and gives every
robot perfect knowledge. An operation takes its shortest draw (the simulation draws
durations within ``jitter`` of the model's: ``duration x (1 - jitter)``) unless the
seed's draws are given: the simulation draws an operation on an object the same in every
run of a seed (:mod:`btcap.sim.mission.opdraws`). The bound is the largest of three:

- **chains**: each object's discovery -> identification -> carry, each step by the
  robot able to do it soonest. An object is discovered no earlier than its cover time
  (:func:`~btcap.sim.mission.cover.cover_times`: the chain of explorations from the
  start, each at a goal beside a covered cell, that can reach it first); identified no
  earlier than that and than an identifier's drive from the start plus its duration; a
  contaminated one carried no earlier than that and than a decontaminator's drive there,
  then its operation and the carry to the decontamination area. The mission ends only
  once every reachable cell is explored (the store's mission is complete only then), so
  no earlier than the last cell's cover time.
- **work**: for every set of task kinds (explore, identify, decontaminate), the work
  only the robots able to do one of them can do, over their presence in time (joins,
  leaves, failures). Exploring the reachable cells at the best duration per cell a
  robot's disc can cover, and no fewer explorations than cells farther apart than the
  widest disc's diameter (:func:`~btcap.sim.mission.cover.apart`); identifying and
  carrying every object at its duration, the carries driven to the decontamination
  area, and the drives to the objects as
  :func:`~btcap.sim.mission.routes.pieces_m` bounds them (from the start or the
  decontamination area; a clean object too where only these robots identify), or at
  least a spanning tree of them (:func:`~btcap.sim.mission.routes.visit_tree_m`).
- **after release**: for every time ``t``, the work on objects that cannot be found (or,
  for carries alone, identified) before ``t`` all happens after ``t`` (the scheduling
  bound for jobs with release times), each robot driving its first piece from wherever it
  stands at ``t`` (:func:`~btcap.sim.mission.routes.pieces_m` with ``anywhere``): no
  farther from the start than it can have driven since it joined (each robot its own
  reach), so that piece is no shorter than the path from the start less that reach (the
  triangle inequality; a gap in its presence only shortens the reach). Then the same
  with each object worked on by one robot at a time (its identification, carry and
  decontamination, each after its release: :mod:`~btcap.sim.mission.preemptive`), so
  robots wait while fewer objects are known than robots can work on.

What it takes from the simulation and the store (:mod:`btcap.sim.world.store`), not from
a mission tree: robots explore only at goals the store hands out and drive along shortest
paths at their speed; only found objects are handed out to identify, only objects found
contaminated to carry; the mission is complete only once every reachable cell is covered
and every object found is finished. Computed in a fraction of a second on the built-in
caves.

What it does not take: that a carry stays whole. A carrier that fails, or is stopped or
sent elsewhere, drops the object where it is (:meth:`~btcap.sim.world.store.MissionState.drop`)
and another may carry it on, so two carriers can share one carry: the work divides as
finely as the work part divides it, and bounds on whole carries (two carriers, three long
carries: one carrier does two) do not hold. Where the paths to the decontamination area
join, one carrier brings an object part of the way and fetches another beyond the join
while the second carrier finishes the first: full-team-6 seed 4 has such a schedule
ending at 273.6 s against this bound's 272.7 s, where the best split of whole carries
ends at 338.8 s (``tests/sim/mission/test_bound_relay.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np

from btcap.sim.mission.cover import apart, cover_times
from btcap.sim.mission.opdraws import Draws, least_factors
from btcap.sim.mission.preemptive import Drive, Job, preemptive_end
from btcap.sim.mission.presence import Presence, finish, presence
from btcap.sim.mission.routes import Legs, pieces_m, visit_tree_m
from btcap.sim.mission.scenario import Scenario
from btcap.sim.mission.seeded import seeded_world
from btcap.sim.world.distance import Cell, distance_field, path_length
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel

__all__ = [
    "Bound",
    "Draws",
    "Presence",
    "cover_times",
    "mission_bound",
    "presence",
    "scenario_bound",
    "visit_tree_m",
]

_KINDS = ("explore", "identify", "decontaminate")


@dataclass(frozen=True, slots=True)
class Bound:
    """The bound (seconds) and its three parts, to say which one binds."""

    seconds: float
    chains_s: float
    work_s: float
    release_s: float

    @property
    def binding(self) -> str:
        """Which part is the bound: chains, work or release."""
        parts = {"chains": self.chains_s, "work": self.work_s, "release": self.release_s}
        return max(parts, key=lambda k: parts[k])


@dataclass(frozen=True, slots=True)
class _Object:
    """One object's figures: its cell, whether dirty, when found and identified at the
    earliest, the least identification and decontamination operation times (seconds),
    and the carry leg (metres to the decontamination area)."""

    cell: Cell
    dirty: bool
    found: float
    ident: float
    id_op: float
    dec_op: float
    back_m: float


def mission_bound(
    grid: GridMap,
    models: Sequence[RobotModel],
    objects: Sequence[tuple[Cell, bool]],
    present: Sequence[Presence] | None = None,
    jitter: float = 0.0,
    draws: Draws | None = None,
) -> Bound:
    """The bound for robots ``models`` (all starting at ``grid.start``, present as
    ``present`` says: default, always) and ``objects`` (cell, contaminated; object ``i``
    of the run is the ``i``-th), durations ``jitter`` shorter at most, or as ``draws``
    says the seed draws them."""
    present = list(present) if present is not None else [Presence()] * len(models)
    cs = grid.cell_size_m
    from_start = distance_field(grid.free, grid.start)
    from_decon = distance_field(grid.free, grid.decon_area)
    able = {k: [i for i, m in enumerate(models) if m.can(k)] for k in _KINDS}

    def least(k: str) -> float:
        return min((models[i].operation(k).duration_s for i in able[k]), default=math.inf)

    # -- chains ---------------------------------------------------------------------
    reach = np.argwhere(grid.reachable)
    cover = cover_times(grid, models, present, jitter)
    explored = float(cover[grid.reachable].max()) if len(reach) else 0.0
    chains = explored
    objs: list[_Object] = []
    for j, (cell, dirty) in enumerate(objects):
        found = float(cover[cell]) if grid.reachable[cell] else math.inf
        drive = path_length(from_start, cell, cs)
        first, extra = least_factors(draws, jitter, "identify", j)
        # the first attempt to end, by whoever is there soonest; a retry by the quickest
        ident = (
            min(
                (
                    max(found, present[i].start + drive / models[i].speed_mps)
                    + models[i].operation("identify").duration_s * first
                    for i in able["identify"]
                ),
                default=math.inf,
            )
            + least("identify") * extra
        )
        end, dec_op, back = ident, 0.0, 0.0
        if dirty:
            back = path_length(from_decon, cell, cs)
            dec_op = least("decontaminate") * sum(least_factors(draws, jitter, "decontaminate", j))
            # picked up by the soonest there, carried (perhaps handed on) at most at the
            # fastest carrier's speed
            picked = min(
                (
                    max(ident, present[i].start + drive / models[i].speed_mps)
                    for i in able["decontaminate"]
                ),
                default=math.inf,
            )
            end = picked + back / _speed(models, able["decontaminate"]) + dec_op
        chains = max(chains, end)
        id_op = least("identify") * (first + extra)
        objs.append(_Object(cell, dirty, found, ident, id_op, dec_op, back))

    legs = Legs(grid, [o.cell for o in objs])
    work_s = _work(grid, models, present, jitter, able, objs, legs)
    release_s = _release(models, present, able, objs, legs)
    release_s = max(release_s, _one_at_a_time(models, present, able, objs, legs, release_s))
    seconds = max(chains, work_s, release_s)
    return Bound(round(seconds, 1), round(chains, 1), round(work_s, 1), round(release_s, 1))


def _speed(models: Sequence[RobotModel], robots: Sequence[int]) -> float:
    return max((models[i].speed_mps for i in robots), default=1.0)


def _drives_s(
    models: Sequence[RobotModel],
    able: dict[str, list[int]],
    objs: Sequence[_Object],
    which: Sequence[int],
    legs: Legs,
    robots: Sequence[int],
    *,
    anywhere: bool,
    since: float = math.inf,
    present: Sequence[Presence] = (),
) -> float:
    """Seconds ``robots`` (the identifiers and decontaminators together) drive for objects
    ``which``: the carries to the decontamination area at the fastest carrier's speed,
    and the pieces to the objects (:func:`pieces_m`) at the fastest one's; clean objects
    count only if no other robot can identify them."""
    dirty = [2 + j for j in which if objs[j].dirty]
    only_ours = set(able["identify"]) <= set(robots)
    clean = [2 + j for j in which if not objs[j].dirty] if only_ours else []
    carry = sum(objs[j].back_m for j in which if objs[j].dirty)
    carry_s = carry / _speed(models, able["decontaminate"]) if dirty else 0.0
    reach = _reach(models, robots, present, since) if anywhere and present else math.inf
    pieces = pieces_m(legs, clean, dirty, len(robots), anywhere=anywhere, reach_m=reach)
    return carry_s + pieces / _speed(models, robots)


def _reach(
    models: Sequence[RobotModel], robots: Sequence[int], present: Sequence[Presence], t: float
) -> list[float]:
    """How far from the start each robot can be at ``t`` (metres)."""
    return [models[i].speed_mps * max(0.0, t - present[i].start) for i in robots]


def _work(
    grid: GridMap,
    models: Sequence[RobotModel],
    present: Sequence[Presence],
    jitter: float,
    able: dict[str, list[int]],
    objs: Sequence[_Object],
    legs: Legs,
) -> float:
    """The work part: see the module's docstring."""
    cs = grid.cell_size_m
    n_cells = int(grid.reachable.sum())
    per_cell = min(
        (
            models[i].operation("explore").duration_s * (1 - jitter) / _disc_cells(models, i, cs)
            for i in able["explore"]
        ),
        default=math.inf,
    )
    every = range(len(objs))
    widest = max((models[i].operation("explore").radius_m for i in able["explore"]), default=0)
    shortest = min(
        (models[i].operation("explore").duration_s * (1 - jitter) for i in able["explore"]),
        default=0.0,
    )
    explorations = apart(grid, widest / cs) * shortest if able["explore"] else 0.0
    ops = {
        "explore": max(n_cells * per_cell if n_cells else 0.0, explorations),
        "identify": sum(o.id_op for o in objs),
        "decontaminate": sum(o.dec_op for o in objs if o.dirty),
    }
    seen = [o.cell for o in objs if grid.reachable[o.cell]]
    visits = visit_tree_m(grid, seen) / _speed(models, able["identify"])
    work_s = 0.0
    for size in (1, 2, 3):
        for kinds in combinations(_KINDS, size):
            robots = sorted({i for k in kinds for i in able[k]})
            total = sum(ops[k] for k in kinds)
            if "decontaminate" in kinds:
                drives = _drives_s(models, able, objs, every, legs, robots, anywhere=False)
                if "identify" in kinds:  # the identifiers drive to every object too
                    drives = max(drives, visits)
                total += drives
            elif "identify" in kinds:
                total += visits
            if total > 0:
                work_s = max(work_s, finish([present[i] for i in robots], 0.0, total))
    return work_s


def _release(
    models: Sequence[RobotModel],
    present: Sequence[Presence],
    able: dict[str, list[int]],
    objs: Sequence[_Object],
    legs: Legs,
) -> float:
    """The after-release part: see the module's docstring."""
    out = 0.0
    carriers = able["decontaminate"]
    for since in {o.ident for o in objs if o.dirty}:  # carries of objects identified later
        later = [j for j, o in enumerate(objs) if o.dirty and o.ident >= since]
        total = sum(objs[j].dec_op for j in later) + _drives_s(
            models,
            {**able, "identify": []},
            objs,
            later,
            legs,
            carriers,
            anywhere=True,
            since=since,
            present=present,
        )
        out = max(out, finish([present[i] for i in carriers], since, total))
    both = sorted(set(carriers) | set(able["identify"]))
    for since in {o.found for o in objs}:  # all the work on objects found later
        later = [j for j, o in enumerate(objs) if o.found >= since]
        ops = sum(objs[j].id_op + objs[j].dec_op for j in later)
        total = ops + _drives_s(
            models, able, objs, later, legs, both, anywhere=True, since=since, present=present
        )
        out = max(out, finish([present[i] for i in both], since, total))
    return out


def _one_at_a_time(
    models: Sequence[RobotModel],
    present: Sequence[Presence],
    able: dict[str, list[int]],
    objs: Sequence[_Object],
    legs: Legs,
    lo: float,
) -> float:
    """The after-release part with each object worked on by one robot at a time
    (:mod:`btcap.sim.mission.preemptive`): the identifiers' identifications, each after
    its discovery, driving to every object (each leaves it for the next); the carriers'
    carries, each after its identification; then both together. The drives after each
    time are those :func:`_release` counts for the objects found (or identified) after
    it, less their carries, which are the jobs' own; a carry of another object may be
    that driving."""
    carriers = able["decontaminate"]
    speed = _speed(models, carriers)
    identifiers = able["identify"]
    points = [j for j, o in enumerate(objs) if o.found < math.inf]

    def carry(j: int) -> tuple[tuple[float, float, bool], ...]:
        o = objs[j]
        return ((o.ident, o.back_m / speed, True), (o.ident, o.dec_op, False)) if o.dirty else ()

    def drive(of: list[int], jobs: list[int], robots: list[int], t: float) -> Drive:
        """The driving of ``robots`` after ``t`` for the objects of ``jobs`` (indices
        into ``of``, the objects of the jobs)."""
        later = [of[k] for k in jobs]
        kinds = able if set(identifiers) <= set(robots) else {**able, "identify": []}
        carried = sum(objs[j].back_m for j in later if objs[j].dirty) / speed
        s = _drives_s(
            models, kinds, objs, later, legs, robots, anywhere=True, since=t, present=present
        )
        return Drive(t, max(0.0, s - carried) if later else 0.0, frozenset(jobs))

    def visits(t: float) -> Drive:
        later = [j for j in points if objs[j].found >= t]
        reach = _reach(models, identifiers, present, t)
        metres = pieces_m(
            legs, [2 + j for j in later], [], len(identifiers), anywhere=True, reach_m=reach
        )
        return Drive(t, metres / _speed(models, identifiers))

    if identifiers:  # no carries among their jobs: any moving of theirs is driving
        lo = preemptive_end(
            [present[i] for i in identifiers],
            [Job(((objs[j].found, objs[j].id_op, False),)) for j in points],
            [visits(t) for t in {0.0} | {objs[j].found for j in points}],
            lo=lo,
        )
    dirty = [j for j in points if objs[j].dirty]  # the carriers' jobs: the carries
    idents = {0.0} | {objs[j].ident for j in dirty}

    def identified(of: list[int], t: float) -> list[int]:
        return [k for k, j in enumerate(of) if objs[j].dirty and objs[j].ident >= t]

    out = preemptive_end(
        [present[i] for i in carriers],
        [Job(carry(j)) for j in dirty],
        [drive(dirty, identified(dirty, t), carriers, t) for t in idents],
        lo=lo,
    )
    both = sorted(set(carriers) | set(identifiers))
    found = [
        drive(points, [k for k, j in enumerate(points) if objs[j].found >= t], both, t)
        for t in {0.0} | {objs[j].found for j in points}
    ]
    drives = [drive(points, identified(points, t), carriers, t) for t in idents] + found
    jobs = [Job(((objs[j].found, objs[j].id_op, False), *carry(j))) for j in points]
    return preemptive_end([present[i] for i in both], jobs, drives, lo=max(lo, out))


def _disc_cells(models: Sequence[RobotModel], i: int, cell_size_m: float) -> int:
    radius_cells = models[i].operation("explore").radius_m / cell_size_m
    r = math.floor(radius_cells)
    d = np.arange(-r, r + 1)
    return int((d[:, None] ** 2 + d[None, :] ** 2 <= radius_cells**2).sum())


def scenario_bound(s: Scenario, *, seed_draws: bool = True) -> Bound:
    """The bound of scenario ``s`` with its objects as the runner scatters them, and the
    operations on them as its seed draws them (``seed_draws``; else the shortest)."""
    w = seeded_world(s)
    return mission_bound(
        w.grid, w.robots, w.objects, w.presence, w.jitter, w.draws if seed_draws else None
    )
