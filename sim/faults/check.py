"""The invariants of the deterministic simulation test, checked as the run goes.

- **Never two at once.** A run acts from its first tick until it ends (finished, stopped
  or its robot gone); while it acts, no other run of the same task ticks — not for a
  tick, whether its robot crashed, froze or was cut off (the fence of
  :mod:`btcap.team.core.fence`: a run acts only while leased, and the origin starts the
  next one only once a run it gave up on surely stopped).
- **A decline means not running.** A robot that declines an award does not hold its
  execution (or the origin would give the task to another robot while it runs here).
- **Nothing credited after failure.** A task's result comes from a run that started after
  the origin last declared its robot failed: the result of a run the origin gave up on
  (of a failed, perhaps restarted, incarnation) is refused.
- **Bounded tables.** What a peer can make a robot hold (members, repository entries,
  leases, hosted runs, pending asks, the transport's drop reasons) stays within bounds
  given by the team and the mission, not by time.

Liveness (the mission completes once the network has healed) is the runner's check.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from btcap.team.core.hosting import FINISHED_KEPT

if TYPE_CHECKING:
    from btcap.team.runtime.agent import Agent

__all__ = ["Checker", "RunRecord"]

#: Drop reasons a transport may count (each a distinct key).
REASONS_KEPT = 16


@dataclass(slots=True)
class RunRecord:
    """One run of an implementation, as its leaf saw it."""

    run: int
    robot: str
    task: str
    first: float
    last: float
    ended: bool = False


@dataclass
class Checker:
    """Collects what runs did and what the origin saw; ``violations`` says what broke."""

    violations: list[str] = field(default_factory=list)
    runs: dict[int, RunRecord] = field(default_factory=dict)
    #: When the origin declared each robot failed: (event count, clock time), in order.
    failed: dict[str, list[tuple[int, float]]] = field(default_factory=dict)
    #: Events so far (runs built, failures declared): orders what happens at one instant.
    events: int = 0
    #: Executions the origin gave up on (lost: re-assigned), by id.
    lost: set[str] = field(default_factory=set)
    _by_task: dict[str, list[RunRecord]] = field(default_factory=dict)
    _reported: set[tuple[int, int]] = field(default_factory=set)
    _next: int = 0
    #: How often a run ticked while another of its task acted (0 unless broken).
    double_ticks: int = 0

    def new_run(self) -> int:
        self._next += 1
        return self._next

    def mark(self) -> int:
        """A point in the order of events (several can happen at one clock instant)."""
        self.events += 1
        return self.events

    # -- executions -----------------------------------------------------------------------
    def tick(self, robot: str, run: int, task: str, now: float) -> None:
        rec = self.runs.get(run)
        if rec is None:
            rec = self.runs[run] = RunRecord(run, robot, task, now, now)
            self._by_task.setdefault(task, []).append(rec)
        else:
            rec.last = now
        for other in self._by_task[task]:
            if other.run == run or other.ended:
                continue
            self.double_ticks += 1
            pair = (min(run, other.run), max(run, other.run))
            if pair not in self._reported:
                self._reported.add(pair)
                a, b = self.runs[pair[0]], self.runs[pair[1]]
                self.violations.append(
                    f"{now:.3f} double execution: task {task} runs on {a.robot} (run {a.run}, "
                    f"acting since {a.first:.3f}) and {b.robot} (run {b.run}, since "
                    f"{b.first:.3f}) at once"
                )

    def end(self, run: int) -> None:
        rec = self.runs.get(run)
        if rec is not None:
            rec.ended = True

    def declined(self, robot: str, execution: str, holds: bool, why: str, now: float) -> None:
        """``robot`` sent a decline of ``execution``; ``holds``: while it holds the run."""
        if holds:
            self.violations.append(
                f"{now:.3f} declined but running: {robot} declined {execution} ({why}) "
                "while it runs it"
            )

    # -- the origin's view ------------------------------------------------------------------
    def declared_failed(self, robot: str, now: float) -> None:
        self.failed.setdefault(robot, []).append((self.mark(), now))

    def gave_up(self, execution: str) -> None:
        """The origin gave ``execution`` up (lost, or its robot failed before its result
        came): it must never be credited."""
        self.lost.add(execution)

    def credit(
        self, origin: str, task: str, robot: str, run: int, execution: str, now: float
    ) -> None:
        """The origin took ``run``'s result for ``task`` from ``execution``."""
        rec = self.runs.get(run)
        if rec is None or rec.robot != robot or rec.task != task:
            self.violations.append(f"{now:.3f} {task} credited to unknown run {run} of {robot}")
            return
        if robot == origin:
            return
        if execution in self.lost:
            when = self.failed.get(robot, [(0, -1.0)])[-1][1]
            self.violations.append(
                f"{now:.3f} credited after failure: {task} to {robot} (run {run}, execution "
                f"{execution}; {robot} last declared failed at {when:.3f})"
            )
            return

    # -- bounds -----------------------------------------------------------------------------
    def bounds(self, now: float, agents: Iterable[Agent], names: int, tasks: int) -> None:
        """Every table a peer can grow, against what this team and mission can need:
        ``names`` robots ever (the origin included) and ``tasks`` capability nodes."""
        for a in agents:
            mc = a.mission_control
            tables = {
                "members": (len(a.team.members), names - 1),
                "repository entries": (len(a.repository.team), names - 1),
                # a task being handed over holds the old run and its paused successor
                "origin leases": (len(mc.origin.tracked), 2 * tasks),
                "active executions": (len(mc.active), 2 * tasks),
                "hosted runs": (len(mc.host.hosted), 2),
                "local runs": (len(mc.executor.local_runs), tasks),
                "pending asks": (a.system.pending_asks, 4 * names + tasks),
                "finished runs kept": (len(mc.host.finished), FINISHED_KEPT),
                # The membership's own tables (being rewritten: read where they are).
                "introductions": (len(getattr(a.team, "_asked", ())), names),
                "rosters awaited": (len(getattr(a.team, "_rosters_due", ())), names),
                "drop reasons": (len(a.system.transport.stats.by_reason), REASONS_KEPT)
                if a.system.transport is not None
                else (0, 0),
            }
            for table, (size, bound) in tables.items():
                if size > bound:
                    self.violations.append(
                        f"{now:.3f} unbounded: {a.robot}'s {table} hold {size} (bound {bound})"
                    )
