"""The work on objects as a preemptive schedule: the after-release part of the mission-time
bound (:mod:`btcap.sim.mission.bound`) with each object worked on by one robot at a time.

The bound's after-release term lets the work on objects found after ``t`` fill every robot
present after ``t``. But an object's work is a sequence no two robots can share in time:
its identification runs on one robot (two attempts begun before either ends draw the same
first factor and fail or succeed alike, so an attempt beside another gains nothing; a
retry begins after an attempt ended), the carry is one object moving with one carrier at
a time (a carry handed on is a drop and a later pick-up), the decontamination comes after
it, on one robot. So while few objects are known, robots wait: with one object found, one
robot works on it and the others can only drive.

:func:`preemptive_end` is the least end of a schedule in which each object's work
(``Job``: its parts, each after its release, at a rate of one robot at most) and
seconds of driving (each ``Drive``: at least so much moving after its time, by any robots
at once) fit in the robots' presence. A carry is moving too: the driving the bound counts
for the objects found after a time may be, in a run, a robot carrying an object found
before it (to the decontamination area on its way), so a carry counts towards the
driving of every ``Drive`` whose objects it is not among. Every run is such a schedule
(each robot does one thing at a time, and only while present), so none ends sooner.
It is the classic bound for identical machines, preemption and release times
(P | pmtn, r_j | Cmax), with machines present in windows and driving to fit in: a linear
program over the spans between releases and presence changes, the end a variable of it
within each span in turn.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from scipy.optimize import linprog

from btcap.sim.mission.presence import Presence

__all__ = ["Drive", "Job", "preemptive_end"]

#: The solver's tolerance, taken off the end it finds (seconds).
_SLACK_S = 1e-3
#: ``linprog``'s status for a problem with no solution.
_INFEASIBLE = 2


@dataclass(frozen=True, slots=True)
class Job:
    """One object's work: its parts as (release, seconds, whether it is moving: a carry),
    done one robot at a time."""

    parts: tuple[tuple[float, float, bool], ...]


@dataclass(frozen=True, slots=True)
class Drive:
    """At least ``seconds`` of moving after ``since``, besides the carries of the jobs
    ``own`` (those of the objects this driving is for)."""

    since: float
    seconds: float
    own: frozenset[int] = frozenset()


def _here(p: Presence, t: float) -> bool:
    """Whether ``p`` is present just after ``t``."""
    return p.start <= t < p.end and not any(g0 <= t < g1 for g0, g1 in p.gaps)


def _least_end(
    present: Sequence[Presence],
    items: Sequence[tuple[int, float, float, bool]],
    drives: Sequence[Drive],
    times: Sequence[float],
    lo: float,
    hi: float,
) -> float | None:
    """The least end in [``lo``, ``hi``] of a schedule of ``items`` (job, release,
    seconds, moving) and ``drives`` over the spans between ``times`` (the last begins at
    ``times[-1]`` and lasts until the end, the robots present as at its start): each item
    split over the spans after its release, some driving in each span, no span holding
    more than its robots' presence nor more of one job than its length, each drive's
    need met after its time; None if there is none."""
    spans = list(pairwise(times))
    last = times[-1]
    cap = [sum(p.within(a, b) for p in present) for a, b in spans]
    robots = sum(_here(p, last) for p in present)
    starts = [a for a, _ in spans] + [last]
    open_ = [k for k in range(len(starts)) if (cap[k] > 0 if k < len(spans) else robots > 0)]
    columns: list[tuple[int, int]] = []  # (item or -1: driving, span); span len(spans): the last
    for i, (_, release, _, _) in enumerate(items):
        usable = [k for k in open_ if starts[k] >= release]
        if not usable:
            return None
        columns += [(i, k) for k in usable]
    columns += [(-1, k) for k in open_]
    n = len(columns) + 1  # the end is the last variable
    a_eq = np.zeros((len(items), n))
    for c, (i, _) in enumerate(columns):
        if i >= 0:
            a_eq[i, c] = 1.0
    groups: dict[tuple[int, int], list[int]] = {}  # (span, job or -2: all) -> columns
    for c, (i, k) in enumerate(columns):
        groups.setdefault((k, -2), []).append(c)
        if i >= 0:
            groups.setdefault((k, items[i][0]), []).append(c)
    rows, b_ub = [], []
    for (k, j), cols in groups.items():
        row = np.zeros(n)
        row[cols] = 1.0
        if k < len(spans):
            b_ub.append(cap[k] if j == -2 else spans[k][1] - spans[k][0])
        else:  # the last span: (end - last) seconds, times its robots for all of them
            width = robots if j == -2 else 1
            row[-1] = -width
            b_ub.append(-width * last)
        rows.append(row)
    for d in drives:  # moving after its time: driving, and carries of other objects
        row = np.zeros(n)
        for c, (i, k) in enumerate(columns):
            if starts[k] >= d.since and (i < 0 or (items[i][3] and items[i][0] not in d.own)):
                row[c] = -1.0
        rows.append(row)
        b_ub.append(-d.seconds)
    cost = np.zeros(n)
    cost[-1] = 1.0
    res = linprog(
        cost,
        A_ub=np.array(rows),
        b_ub=np.array(b_ub),
        A_eq=a_eq,
        b_eq=np.array([s for _, _, s, _ in items]),
        bounds=[(0.0, None)] * (n - 1) + [(max(lo, last), hi)],
        method="highs",
    )
    if res.status == 0:
        return float(res.x[-1])
    if res.status == _INFEASIBLE:
        return None  # no schedule ends in this span: the end lies later
    # The solver could not tell (numerical trouble, a limit): the span's start is the
    # least end it allows, so the bound stays below every schedule rather than above.
    return max(lo, last)


def preemptive_end(
    present: Sequence[Presence],
    jobs: Sequence[Job],
    drives: Sequence[Drive] = (),
    *,
    lo: float = 0.0,
) -> float:
    """The least end of a schedule of ``jobs`` and ``drives`` by robots present as
    ``present`` says (no sooner than ``lo``, a known lower bound; inf if none fits).

    The end lies between two successive changes (a release, a drive's time, a robot
    joining, leaving, failing or back): it is sought between each two in turn, from the
    one ``lo`` is in, the spans before it fixed and the last one ending at the end."""
    items = [(j, r, s, m) for j, job in enumerate(jobs) for r, s, m in job.parts if s > 0]
    drives = [d for d in drives if d.seconds > 0]
    if not items and not drives:
        return lo
    cuts = {0.0, *(r for _, r, _, _ in items), *(d.since for d in drives)}
    for p in present:
        cuts |= {p.start, p.end, *(t for g in p.gaps for t in g)}
    times = sorted(t for t in cuts if t < math.inf)
    for k in range(len(times)):
        after = times[k + 1] if k + 1 < len(times) else math.inf
        if after <= lo:
            continue
        end = _least_end(present, items, drives, times[: k + 1], lo, after)
        if end is not None:
            return max(lo, end - _SLACK_S)
    return math.inf
