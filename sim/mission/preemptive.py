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
seconds of driving (each ``Drive``: at least so much driving after its time, by any
robots at once) fit in the robots' presence. Every run is such a schedule (each robot does
one thing at a time, and only while present), so none ends sooner. It is the classic
bound for identical machines, preemption and release times (P | pmtn, r_j | Cmax, a
max-flow), with machines present in windows: a linear program over the intervals between
releases and presence changes, solved for the least end by bisection.
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

#: Bisection stops once the end is known to this many seconds.
_TOLERANCE_S = 0.01


@dataclass(frozen=True, slots=True)
class Job:
    """One object's work: its parts as (release, seconds), done one robot at a time."""

    parts: tuple[tuple[float, float], ...]


@dataclass(frozen=True, slots=True)
class Drive:
    """At least ``seconds`` of driving after ``since``."""

    since: float
    seconds: float


def _chunks(drives: Sequence[Drive]) -> list[tuple[float, float]]:
    """The drives as chunks (release, seconds) each done after its release: driving after
    ``t`` is no less than any later requirement either, so each time's need is the most of
    its own and every later one's, and the chunks are the steps of that need."""
    need: list[tuple[float, float]] = []
    most = 0.0
    for d in sorted(drives, key=lambda d: -d.since):
        most = max(most, d.seconds)
        need.append((d.since, most))
    need.reverse()  # by time: need falls as time grows
    out = []
    for k, (since, seconds) in enumerate(need):
        later = need[k + 1][1] if k + 1 < len(need) else 0.0
        if seconds > later:
            out.append((since, seconds - later))
    return out


def _fits(
    present: Sequence[Presence],
    jobs: Sequence[Job],
    chunks: Sequence[tuple[float, float]],
    end: float,
) -> bool:
    """Whether the jobs and drive chunks fit in the robots' presence before ``end``: a
    feasibility program over the spans between releases and presence changes, each part
    and chunk split over the spans after its release, no span holding more than its
    robots' presence, nor more of one job than its length."""
    cuts = {0.0, end}
    for p in present:
        cuts |= {p.start, p.end, *(t for g in p.gaps for t in g)}
    cuts |= {r for j in jobs for r, _ in j.parts} | {r for r, _ in chunks}
    times = sorted(t for t in cuts if 0.0 <= t <= end)
    spans = [(a, b) for a, b in pairwise(times) if b > a]
    cap = [sum(p.within(a, b) for p in present) for a, b in spans]
    rows: list[list[int]] = []  # for each (job part | chunk): its columns
    owner: list[int] = []  # each column's job (-1: a drive)
    span_of: list[int] = []
    demand: list[float] = []
    items = [(j, r, s) for j, job in enumerate(jobs) for r, s in job.parts if s > 0]
    items += [(-1, r, s) for r, s in chunks]
    for j, release, seconds in items:
        usable = [k for k, (a, _) in enumerate(spans) if a >= release and cap[k] > 0]
        if not usable:
            return False
        rows.append(list(range(len(owner), len(owner) + len(usable))))
        owner += [j] * len(usable)
        span_of += usable
        demand.append(seconds)
    n = len(owner)
    if n == 0:
        return True
    a_eq = np.zeros((len(rows), n))
    for i, cols in enumerate(rows):
        a_eq[i, cols] = 1.0
    limits: dict[tuple[int, int], list[int]] = {}  # (span, job or -1) -> its columns
    for c, (j, k) in enumerate(zip(owner, span_of, strict=True)):
        limits.setdefault((k, -2), []).append(c)  # everything in the span
        if j >= 0:
            limits.setdefault((k, j), []).append(c)
    a_ub = np.zeros((len(limits), n))
    b_ub = np.zeros(len(limits))
    for i, ((k, j), cols) in enumerate(limits.items()):
        a_ub[i, cols] = 1.0
        b_ub[i] = cap[k] if j == -2 else spans[k][1] - spans[k][0]
    res = linprog(
        np.zeros(n), A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=np.array(demand), method="highs"
    )
    return bool(res.status == 0)


def preemptive_end(
    present: Sequence[Presence],
    jobs: Sequence[Job],
    drives: Sequence[Drive] = (),
    *,
    lo: float = 0.0,
) -> float:
    """The least end of a schedule of ``jobs`` and ``drives`` by robots present as
    ``present`` says (no sooner than ``lo``, a known lower bound; inf if none fits)."""
    chunks = _chunks([d for d in drives if d.seconds > 0])
    if not any(s > 0 for j in jobs for _, s in j.parts) and not chunks:
        return lo
    if _fits(present, jobs, chunks, lo):  # the common case: the bound is known already
        return lo
    known = lo
    hi = max(lo, 1.0) * 2
    while not _fits(present, jobs, chunks, hi):
        if hi > 1e7:
            return math.inf
        lo, hi = hi, hi * 2
    while hi - lo > _TOLERANCE_S:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if _fits(present, jobs, chunks, mid) else (mid, hi)
    # no schedule ends by ``lo``: less the solver's tolerance, in case it is one
    return max(known, lo - _TOLERANCE_S)
