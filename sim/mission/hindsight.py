"""A schedule made in hindsight: how soon the object work could end if every robot knew
where the objects lie, when each is found and what each operation's draws are.

The mission-time bound (:mod:`btcap.sim.mission.bound`) is below every run, and its
parts but the exploration work are below the best schedule of a world that relaxes the
real one; this is one schedule of that world, so above its best. Where it equals the
bound, the bound has no slack in that world and what is left of a mission's gap is the
mission's or the relaxation's; where it is above, at most that much is the bound's.

The world is the bound's: each object is found at its cover time
(:func:`~btcap.sim.mission.cover.cover_times`; exploring costs the other robots nothing),
robots drive shortest paths at their speed, from the start once present, and are out of
the team during their gaps and after leaving; an object's identification is done by one
robot, again until its draws say it succeeds; a contaminated one is carried by one robot
from where it lies to the decontamination area (at that robot's speed) and
decontaminated there, again until it succeeds. The mission ends no sooner than its last
cell's cover time. Keeping each carry whole is this world's, not the simulator's: there
a carrier that is stopped drops the object and another may carry it on, which can end
sooner (full-team-6 seed 4: 273.6 s handed on where two paths join, against 338.8 s
here; ``tests/sim/mission/test_bound_relay.py``), so where this schedule is above the
bound, part of the gap may be its own. The schedule is the best one of many task orders,
each decoded greedily (each task, in turn, to the robot able to end it soonest, or to the one a
robot choice says) and improved by moving a task to another robot or swapping two while
that ends the work sooner: feasible in that world, not proven to be its best.
:func:`walked_found` gives, instead of the cover times, when the robots that only
explore find each object walking the store's goals nearest first.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from btcap.sim.mission.cover import cover_times
from btcap.sim.mission.opdraws import Draws
from btcap.sim.mission.presence import Presence
from btcap.sim.mission.routes import Legs
from btcap.sim.mission.scenario import Scenario
from btcap.sim.mission.seeded import seeded_world
from btcap.sim.world.distance import Cell, distance_field
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel
from btcap.sim.world.store import MissionState

__all__ = ["Hindsight", "hindsight_schedule", "scenario_hindsight", "walked_found"]


@dataclass(frozen=True, slots=True)
class Hindsight:
    """The schedule's end (seconds), its object work's end alone, and each robot's busy
    seconds (driving and working; the robots in the order given)."""

    seconds: float
    work_end_s: float
    busy_s: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class _Task:
    obj: int
    carry: bool
    release: float  # found (identify); carries are released by their identification
    factor: float  # the sum of its attempts' factors


def _fit(p: Presence, depart: float, drive: float, ready: float, work: float) -> float:
    """The earliest departure, no sooner than ``depart``, for a drive of ``drive`` s then
    ``work`` s of work begun no sooner than ``ready``, all while present; inf if none.
    The robot leaves as late as still lets the work begin at its earliest."""
    if not p.gaps:  # the common case, quickly
        d = max(depart, p.start)
        begin = max(d + drive, ready)
        return max(d, begin - drive) if begin + work <= p.end else math.inf
    candidates = [depart, p.start, *(g1 for _, g1 in p.gaps)]
    for d in sorted(c for c in candidates if c >= depart):
        begin = max(d + drive, ready)
        d = max(d, begin - drive)
        end = begin + work
        if d < p.start or end > p.end:
            continue
        if any(g0 < end and d < g1 for g0, g1 in p.gaps):
            continue
        return d
    return math.inf


class _World:
    def __init__(
        self,
        grid: GridMap,
        models: Sequence[RobotModel],
        present: Sequence[Presence],
        tasks: Sequence[_Task],
        cells: Sequence[Cell],
    ) -> None:
        self.models, self.present, self.tasks = list(models), list(present), list(tasks)
        self.m = Legs(grid, cells).m.tolist()  # floats: quicker to index than numpy's
        kinds = ["decontaminate" if t.carry else "identify" for t in tasks]
        self.able = [{k for k in range(len(tasks)) if m.can(kinds[k])} for m in models]
        self.work = [  # each robot's seconds of work on each task, a carry's drive too
            [
                m.operation(kinds[k]).duration_s * t.factor
                + (self.m[2 + t.obj][1] / m.speed_mps if t.carry else 0.0)
                if k in self.able[i]
                else math.inf
                for k, t in enumerate(tasks)
            ]
            for i, m in enumerate(models)
        ]

    def decode(
        self,
        order: Sequence[int],
        gene: list[int] | None = None,
        plan: list[tuple[int, int, bool, float, float]] | None = None,
    ) -> tuple[float, list[float], list[int]]:
        """Each task in ``order`` (identifications before their carries) to its robot in
        ``gene``, or, where that is -1 or unable, to the robot able to end it soonest: the
        object work's end, each robot's busy seconds and the robots chosen."""
        n = len(self.models)
        free = [p.start for p in self.present]
        at = [0] * n  # index into the legs: 0 start, 1 decontamination area, 2 + object
        busy = [0.0] * n
        chosen = [-1] * len(self.tasks)
        ident_end: dict[int, float] = {}
        end_all = 0.0
        for k in order:
            t = self.tasks[k]
            ready = ident_end.get(t.obj, math.inf) if t.carry else t.release
            best = (math.inf, -1, 0.0, 0.0)
            want = gene[k] if gene is not None else -1
            for i in [want] if want >= 0 and k in self.able[want] else range(n):
                if k not in self.able[i]:
                    continue
                model = self.models[i]
                drive = self.m[at[i]][2 + t.obj] / model.speed_mps
                work = self.work[i][k]
                d = _fit(self.present[i], free[i], drive, ready, work)
                if math.isinf(d):
                    continue
                end = max(d + drive, ready) + work
                if end < best[0]:
                    best = (end, i, drive, work)
            end, i, drive, work = best
            if i < 0:
                return math.inf, busy, chosen
            if plan is not None:  # robot, object, carry, work's start and end
                plan.append((i, t.obj, t.carry, end - work, end))
            free[i], at[i] = end, 1 if t.carry else 2 + t.obj
            busy[i] += float(drive + work)
            chosen[k] = i
            if not t.carry:
                ident_end[t.obj] = end
            end_all = max(end_all, end)
        return end_all, busy, chosen


def _valid(order: list[int], tasks: Sequence[_Task]) -> bool:
    seen: set[int] = set()
    for k in order:
        if tasks[k].carry and tasks[k].obj not in seen:
            return False
        if not tasks[k].carry:
            seen.add(tasks[k].obj)
    return True


def hindsight_schedule(
    grid: GridMap,
    models: Sequence[RobotModel],
    objects: Sequence[tuple[Cell, bool]],
    present: Sequence[Presence],
    jitter: float,
    draws: Draws,
    *,
    tries: int = 300,
    seed: int = 0,
    plan: list[tuple[int, int, bool, float, float]] | None = None,
    found: tuple[Sequence[float], float] | None = None,
) -> Hindsight:
    """The best of ``tries`` random task orders (and the found-first order), each
    improved by swapping pairs of tasks while that ends the work sooner."""
    cover = cover_times(grid, models, present, jitter)
    explored = float(cover[grid.reachable].max()) if grid.reachable.any() else 0.0
    if found is not None:
        explored = found[1]
    tasks: list[_Task] = []
    cells: list[Cell] = []
    for j, (cell, dirty) in enumerate(objects):
        if not grid.reachable[cell]:
            continue
        obj = len(cells)
        cells.append(cell)
        at = float(cover[cell]) if found is None else found[0][j]
        tasks.append(_Task(obj, False, at, sum(draws.attempts("identify", j))))
        if dirty:
            tasks.append(_Task(obj, True, at, sum(draws.attempts("decontaminate", j))))
    world = _World(grid, models, present, tasks, cells)
    rng = np.random.default_rng(seed)
    first = sorted(range(len(tasks)), key=lambda k: (tasks[k].release, tasks[k].carry))
    best_end, best_busy, best = math.inf, [0.0] * len(models), (first, [-1] * len(tasks))
    for attempt in range(tries):
        order = first if attempt == 0 else _random_order(rng, tasks)
        end, busy, gene = world.decode(order)
        end, busy, order, gene = _improve(world, order, gene, end, busy)
        if end < best_end:
            best_end, best_busy, best = end, busy, (order, gene)
    if plan is not None:
        world.decode(*best, plan=plan)
    return Hindsight(
        round(max(best_end, explored), 1),
        round(best_end, 1),
        tuple(round(b, 1) for b in best_busy),
    )


def _improve(
    world: _World, order: list[int], gene: list[int], end: float, busy: list[float]
) -> tuple[float, list[float], list[int], list[int]]:
    """Hill-climb from ``order`` and ``gene``: move a task to another robot, or swap two
    tasks in the order (their robots kept or chosen afresh), while that ends the work
    sooner."""
    tasks = world.tasks
    improved = True
    while improved:
        improved = False
        for k in range(len(tasks)):
            for i in range(len(world.models)):
                if i == gene[k] or k not in world.able[i]:
                    continue
                trial_gene = gene.copy()
                trial_gene[k] = i
                e, bz, _ = world.decode(order, trial_gene)
                if e < end - 1e-9:
                    gene, end, busy, improved = trial_gene, e, bz, True
        for a in range(len(order)):
            for b in range(a + 1, len(order)):
                trial = order.copy()
                trial[a], trial[b] = trial[b], trial[a]
                if not _valid(trial, tasks):
                    continue
                for g in (gene, None):  # its robots as they were, or chosen afresh
                    e, bz, chosen = world.decode(trial, g)
                    if e < end - 1e-9:
                        order, gene, end, busy, improved = trial, chosen, e, bz, True
                        break
    return end, busy, order, gene


def _random_order(rng: np.random.Generator, tasks: Sequence[_Task]) -> list[int]:
    """A random order of the tasks with each carry after its identification."""
    order = [int(k) for k in rng.permutation(len(tasks))]
    pos = {(tasks[k].obj, tasks[k].carry): i for i, k in enumerate(order)}
    for obj in {t.obj for t in tasks if t.carry}:
        a, b = pos[(obj, False)], pos[(obj, True)]
        if a > b:
            order[a], order[b] = order[b], order[a]
    return order


def walked_found(
    grid: GridMap,
    models: Sequence[RobotModel],
    present: Sequence[Presence],
    objects: Sequence[tuple[Cell, bool]],
    draws: Draws,
) -> tuple[list[float], float] | None:
    """When each object is found, and the last cell, if the robots that can only explore
    walk the store's goals, each taking the pending goal nearest to it when it comes
    free (explorations at the seed's draws, again until they succeed); None if no robot
    only explores."""
    pure = _only_explore(models)
    if not pure:
        return None
    state = MissionState(grid, [], rng=np.random.default_rng(0))
    cs = grid.cell_size_m
    first = np.full(grid.shape, math.inf)
    ready = [(present[i].start, i, grid.start) for i in pure]  # (free at, robot, cell)
    running: list[tuple[float, int, Cell, int]] = []  # (ends, robot, cell, goal id)
    while ready or running:
        ready.sort()
        running.sort()
        if ready and (not running or ready[0][0] < running[0][0]):  # ends come first
            t, i, at = ready.pop(0)
            pending = [g for g in state.pending_goals() if g.claimed_by is None]
            if t >= present[i].end:
                continue
            if not pending:
                if running:  # a goal may come with the next exploration's end
                    ready.append((running[0][0], i, at))
                continue
            steps = distance_field(grid.free, at)
            goal = min(pending, key=lambda g: (steps[g.cell], g.id))
            goal.claimed_by = str(i)
            op = models[i].operation("explore")
            factor = sum(draws.attempts("explore", -1, cell=goal.cell))
            end = t + steps[goal.cell] * cs / models[i].speed_mps + op.duration_s * factor
            running.append((end, i, goal.cell, goal.id))
        else:
            end, i, cell, goal_id = running.pop(0)
            before = state.covered.copy()
            state.explore(cell, models[i].operation("explore").radius_m)
            state.goal_done(goal_id)
            first[state.covered & ~before] = end
            ready.append((end, i, cell))
    last = float(first[grid.reachable].max()) if grid.reachable.any() else 0.0
    return [float(first[cell]) for cell, _ in objects], last


def _only_explore(models: Sequence[RobotModel]) -> list[int]:
    """The robots that can explore and nothing else."""
    return [
        i
        for i, m in enumerate(models)
        if m.can("explore") and not m.can("identify") and not m.can("decontaminate")
    ]


def scenario_hindsight(s: Scenario, *, tries: int = 20) -> Hindsight | None:
    """The schedule of scenario ``s`` made in hindsight, its objects as the runner
    scatters them and their operations as its seed draws them; None where no robot only
    explores (then the robots that do the object work explore too, which this world
    leaves out: its schedule could end before the bound)."""
    w = seeded_world(s)
    if not _only_explore(w.robots):
        return None
    return hindsight_schedule(
        w.grid, w.robots, w.objects, w.presence, w.jitter, w.draws, tries=tries
    )
