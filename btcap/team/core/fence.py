"""The fence that keeps one task on one robot at a time, on explicit time (sans-IO).

Two clocks, no shared time: each side measures only durations on its own monotonic clock,
and the clocks' rates differ from true time by at most :data:`DRIFT` (±1 %).

- **The executor** stamps what it sends about a run with its own clock; the origin echoes
  the newest stamp it heard in every renewal (inputs, keep-alives). A run is *leased*
  until the echoed stamp plus ``lease_s`` x :data:`EXECUTOR_SHARE`, and it acts only while
  leased: it starts at its first renewal (an award alone starts nothing, so an award that
  was withdrawn and arrives late never runs) and is stopped when the lease ends, with or
  without word from the origin. A stamp is older than the renewal echoing it, so however
  late a renewal arrives it never leases a run past the echoed stamp's time plus the share.
- **The origin** counts from when the newest stamp it echoes arrived (the stamp is older
  than that; words without a newer stamp renew nothing): ``lease_s`` later on its clock,
  the run can no longer act,
  as ``lease_s / (1 + DRIFT)`` true seconds exceed ``lease_s x EXECUTOR_SHARE /
  (1 - DRIFT)`` by :data:`STOP_SLACK` x ``lease_s`` (the executor's time to stop). Until
  then a task whose run it gave up on (its robot declared failed, the run moved or
  cancelled without a confirmation) starts no other run: :class:`Fences` holds the
  task's next award paused.

A confirmation ends the wait early: a robot that stopped a run (cancelled, lease lapsed,
finished) says so, and a run that said so never acts again.
"""

from __future__ import annotations

from typing import Protocol

from btcap.team.ids import ExecutionId

__all__ = [
    "DRIFT",
    "EXECUTOR_SHARE",
    "STOP_SLACK",
    "Fences",
    "executor_lease_s",
    "speedup_of",
    "speedups_differ",
]

#: The largest difference between a robot clock's rate and true time (±1 %: quartz is
#: within 0.01 %, NTP slews at most 0.05 %).
DRIFT = 0.01
#: The share of ``lease_s`` an executor's run lives past the stamp its origin echoed.
EXECUTOR_SHARE = 0.9
#: What is left for the executor to stop its run, as a share of ``lease_s`` (0.08: 64 ms
#: at the default 0.8 s lease), with both clocks at the worst drift.
STOP_SLACK = 1.0 / (1.0 + DRIFT) - EXECUTOR_SHARE / (1.0 - DRIFT)


class _Rated(Protocol):
    def to_wall(self, seconds: float) -> float: ...


def speedup_of(clock: _Rated) -> float:
    """A clock's speed-up (clock seconds per wall second), 0.0 for a virtual clock."""
    wall = clock.to_wall(1.0)
    return 1.0 / wall if wall > 0 else 0.0


def speedups_differ(ours: float, theirs: float) -> bool:
    """Whether two robots' clocks run at rates the fence was not made for: the leases
    are clock seconds, and it holds for rates within :data:`DRIFT` of each other (a
    speed-up of 0: a virtual clock, or not said, is not judged)."""
    if ours <= 0 or theirs <= 0:
        return False
    return abs(ours / theirs - 1.0) > 2 * DRIFT


def executor_lease_s(lease_s: float) -> float:
    """How long an executor's run lives past the newest stamp its origin echoed."""
    return lease_s * EXECUTOR_SHARE


class Fences:
    """Per task (a capability node's path): the runs given up on that may still act on
    their robots, each until when (origin clock). Entries end at their time or on the
    robot's confirmation, so the table holds at most the runs given up in one lease."""

    def __init__(self) -> None:
        self._tasks: dict[str, dict[tuple[ExecutionId, str], float]] = {}

    def __len__(self) -> int:
        return sum(len(runs) for runs in self._tasks.values())

    def hold(self, execution: ExecutionId, robot: str, until: float, now: float) -> None:
        """``robot``'s run of ``execution`` was given up on and may act until ``until``."""
        if until <= now:
            return
        runs = self._tasks.setdefault(execution.node, {})
        key = (execution, robot)
        runs[key] = max(until, runs.get(key, until))

    def stopped(self, execution: ExecutionId, robot: str) -> None:
        """``robot`` said its run of ``execution`` ended: it acts no more."""
        runs = self._tasks.get(execution.node)
        if runs is not None and runs.pop((execution, robot), None) is not None and not runs:
            del self._tasks[execution.node]

    def until(self, task: str, now: float) -> float | None:
        """Until when ``task`` must wait before a new run of it may act, or None: it may
        now (entries past their time are forgotten)."""
        runs = self._tasks.get(task)
        if runs is None:
            return None
        for key in [k for k, t in runs.items() if t <= now]:
            del runs[key]
        if not runs:
            del self._tasks[task]
            return None
        return max(runs.values())

    def expire(self, now: float) -> None:
        """Forget every entry past its time."""
        if not self._tasks:  # the usual case: checked every keep-alive round
            return
        for task in list(self._tasks):
            self.until(task, now)
