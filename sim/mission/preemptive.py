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
max-flow), with machines present in windows: a linear program over the spans between
releases and presence changes, the end a variable of it within each span in turn.
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


def _here(p: Presence, t: float) -> bool:
    """Whether ``p`` is present just after ``t``."""
    return p.start <= t < p.end and not any(g0 <= t < g1 for g0, g1 in p.gaps)


def _least_end(
    present: Sequence[Presence],
    items: Sequence[tuple[int, float, float]],
    times: Sequence[float],
    lo: float,
    hi: float,
) -> float | None:
    """The least end in [``lo``, ``hi``] of a schedule of ``items`` (job or -1 for a
    drive, release, seconds) over the spans between ``times`` (the last begins at
    ``times[-1]`` and lasts until the end, the robots present as at its start), each
    item split over the spans after its release, no span holding more than its robots'
    presence nor more of one job than its length; None if there is none."""
    spans = list(pairwise(times))
    last = times[-1]
    cap = [sum(p.within(a, b) for p in present) for a, b in spans]
    robots = sum(_here(p, last) for p in present)
    columns: list[tuple[int, int]] = []  # (item, span); span len(spans): the last
    for i, (_, release, _) in enumerate(items):
        usable = [k for k, (a, _) in enumerate(spans) if a >= release and cap[k] > 0]
        if release <= last and robots > 0:
            usable.append(len(spans))
        if not usable:
            return None
        columns += [(i, k) for k in usable]
    n = len(columns) + 1  # the end is the last variable
    a_eq = np.zeros((len(items), n))
    for c, (i, _) in enumerate(columns):
        a_eq[i, c] = 1.0
    groups: dict[tuple[int, int], list[int]] = {}  # (span, job or -2: all) -> columns
    for c, (i, k) in enumerate(columns):
        groups.setdefault((k, -2), []).append(c)
        if items[i][0] >= 0:
            groups.setdefault((k, items[i][0]), []).append(c)
    a_ub = np.zeros((len(groups), n))
    b_ub = np.zeros(len(groups))
    for row, ((k, j), cols) in enumerate(groups.items()):
        a_ub[row, cols] = 1.0
        if k < len(spans):
            b_ub[row] = cap[k] if j == -2 else spans[k][1] - spans[k][0]
        else:  # the last span: (end - last) seconds, times its robots for all of them
            width = robots if j == -2 else 1
            a_ub[row, -1] = -width
            b_ub[row] = -width * last
    cost = np.zeros(n)
    cost[-1] = 1.0
    bounds = [(0.0, None)] * (n - 1) + [(max(lo, last), hi)]
    res = linprog(
        cost,
        A_ub=a_ub,
        b_ub=b_ub,
        A_eq=a_eq,
        b_eq=np.array([s for _, _, s in items]),
        bounds=bounds,
        method="highs",
    )
    return float(res.x[-1]) if res.status == 0 else None


def preemptive_end(
    present: Sequence[Presence],
    jobs: Sequence[Job],
    drives: Sequence[Drive] = (),
    *,
    lo: float = 0.0,
) -> float:
    """The least end of a schedule of ``jobs`` and ``drives`` by robots present as
    ``present`` says (no sooner than ``lo``, a known lower bound; inf if none fits).

    The end lies between two successive changes (a release, a robot joining, leaving,
    failing or back): it is sought between each two in turn, from the one ``lo`` is in,
    the spans before it fixed and the last one ending at the end."""
    items = [(j, r, s) for j, job in enumerate(jobs) for r, s in job.parts if s > 0]
    items += [(-1, r, s) for r, s in _chunks([d for d in drives if d.seconds > 0])]
    if not items:
        return lo
    cuts = {0.0, *(r for _, r, _ in items)}
    for p in present:
        cuts |= {p.start, p.end, *(t for g in p.gaps for t in g)}
    times = sorted(t for t in cuts if t < math.inf)
    for k in range(len(times)):
        after = times[k + 1] if k + 1 < len(times) else math.inf
        if after <= lo:
            continue
        end = _least_end(present, items, times[: k + 1], lo, after)
        if end is not None:
            return max(lo, end - _SLACK_S)
    return math.inf
