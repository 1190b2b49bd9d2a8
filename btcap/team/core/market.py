"""An origin's side of consensus allocation: the price board of its own open tasks.

Consensus allocation is the auction algorithm (Bertsekas 1979/1988) run by the robots
themselves: every robot decides what it bids from its own costs and the prices it knows
(:mod:`btcap.team.core.consensus`); no robot sees another's costs or decides for it.
Each task's price is a register kept by the one robot that may speak for the task, its
origin (which alone awards it, as before): the highest bid on it so far (ties to the lower
robot id), and who made it, the **holder**. A bid lower than the price is refused, a
higher one outbids the holder; either way the robot that must bid again is sent the
board (:meth:`Market.board`), and nobody else is.

Within one task set (``version``) prices only rise, which is what makes the auction end;
opening a task, a candidate declining an award or a holder going (lost, or moving on)
raise the ``version``: every candidate hears the new set and reports again, and a task
whose holder went is auctioned afresh (price 0). The origin has **converged** when every
live candidate not under suspicion of failure has reported having seen the current set
and either holds one of its tasks or claims something else (or nothing): nobody would
bid again until something changes (a suspect is waited for by nobody).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Generic, TypeVar

from btcap.team.ids import ExecutionId

__all__ = ["CEILING_MARGIN", "Board", "Claim", "Market", "Task"]

T = TypeVar("T")

#: The outside option (the cost of claiming nothing) is this much over the dearest cost
#: any candidate reported: every task is worth taking, so none is left for want of price.
CEILING_MARGIN = 0.01


@dataclass(frozen=True, slots=True)
class Claim:
    """What ``robot`` says it wants under its ``stamp``: ``task``, whose running costs it
    ``cost`` (lower is better), for which it bids the price ``bid``; or nothing."""

    robot: str
    stamp: int
    task: ExecutionId | None = None
    cost: float = math.inf
    bid: float = 0.0
    #: the robot's dearest finite cost among the open tasks (the team's sets the ceiling)
    most: float = 0.0


@dataclass(frozen=True, slots=True)
class Task(Generic[T]):
    """An open task: who may run it, and the origin's description (opaque here)."""

    id: ExecutionId
    candidates: frozenset[str]
    spec: T


@dataclass(frozen=True, slots=True)
class Board:
    """``origin``'s prices in its task set ``version``, numbered ``seq``: each open
    task's price and holder; ``heard``: the newest claim stamp of the recipient it
    reflects (an older board says nothing about a claim still on its way)."""

    origin: str
    version: int
    seq: int
    heard: int
    prices: tuple[tuple[ExecutionId, float, str | None], ...]
    ceiling: float = 0.0


@dataclass(slots=True)
class _Report:
    version: int  # of our task set, as the robot had merged it
    claim: Claim


class Market(Generic[T]):
    """The board of ``origin``'s open tasks; see the module docstring. ``refused``
    counts bids that made no sense (the shell logs it)."""

    def __init__(self, origin: str) -> None:
        self.origin = origin
        self.tasks: dict[ExecutionId, Task[T]] = {}
        self.version = 0
        self.members: set[str] = {origin}
        self.top: dict[ExecutionId, tuple[float, str | None]] = {}
        self.reports: dict[str, _Report] = {}
        self.owed: set[str] = set()  # robots to send the board to: they must bid again
        self.refused = 0
        self.ceiling = 0.0  # the outside option: over every cost a candidate reported
        self.suspected: frozenset[str] = frozenset()  # members nobody waits for now
        self._seq = 0

    # -- the team and the task set -----------------------------------------------------
    def join(self, robot: str) -> None:
        self.members.add(robot)

    def lose(self, robot: str) -> None:
        """A member left or failed: what it held is free (at its price) for the others."""
        self.members.discard(robot)
        self.suspected -= {robot}
        self.owed.discard(robot)
        gone = self.reports.pop(robot, None)
        if gone is not None and self._holds(robot, gone.claim.task):
            self._free(gone.claim.task)

    def suspect(self, robots: frozenset[str]) -> None:
        """The members under suspicion of failure now (the whole set, each step): nobody
        waits for them, and what one of them holds is auctioned afresh as if it were lost
        (its award would wait on a robot likely gone). A suspect is still told and heard:
        a claim it makes later may win again, and once its suspicion ends (refuted) it is
        waited for again."""
        robots = frozenset(robots & self.members - {self.origin})
        for robot in sorted(robots - self.suspected):
            report = self.reports.get(robot)
            if report is not None and self._holds(robot, report.claim.task):
                self._free(report.claim.task)
        self.suspected = robots

    def open(self, task: Task[T]) -> None:
        if task.id.origin != self.origin:
            raise ValueError(f"task {task.id}: only its origin {task.id.origin} offers it")
        self.tasks[task.id] = task
        self.version += 1

    def close(self, task: ExecutionId) -> None:
        """Awarded or withdrawn: its holder is told (the others learn it when a bid for it
        is refused)."""
        if self.tasks.pop(task, None) is not None:
            _price, holder = self.top.pop(task, (0.0, None))
            if holder is not None:
                self.owed.add(holder)

    def restrict(self, task: ExecutionId, robot: str) -> None:
        """``robot`` may no longer take ``task`` (it declined the award)."""
        t = self.tasks.get(task)
        if t is not None and robot in t.candidates:
            self.tasks[task] = Task(t.id, t.candidates - {robot}, t.spec)
            if self._holds(robot, task):
                self._free(task)
            else:
                self.version += 1

    def _free(self, task: ExecutionId | None, *, keep_price: bool = False) -> None:
        """Its holder went: everyone must hear of the task again. A holder that moved on to
        another task leaves the price where it was (prices that fell back to 0 drew it
        back, and two origins' tasks could trade one robot for ever: heavy sim-test seed
        70055); one that failed or declined leaves a new auction."""
        if task is not None:
            if keep_price and task in self.top:
                self.top[task] = (self.top[task][0], None)
            else:
                self.top.pop(task, None)
        self.version += 1

    def _holds(self, robot: str, task: ExecutionId | None) -> bool:
        return task is not None and task in self.top and self.top[task][1] == robot

    # -- bids ----------------------------------------------------------------------------
    def hear(self, claim: Claim, version: int) -> bool:
        """``claim.robot``'s claim, made having merged our task set ``version``; True if
        news. A bid on one of our tasks outbids its holder if it is higher (ties: the
        lower robot id), else it is refused; the loser is owed the board."""
        robot = claim.robot
        if robot not in self.members:
            return False
        if not (math.isfinite(claim.bid) and claim.bid >= 0):
            self.refused += 1
            return False
        old = self.reports.get(robot)
        if old is not None and claim.stamp < old.claim.stamp:
            return False  # overtaken
        if old is not None and claim.stamp == old.claim.stamp:
            old.version = max(old.version, version)
            if old.claim.task in self.tasks and not self._holds(robot, old.claim.task):
                self.owed.add(robot)  # it says it again: our answer was lost
            return False
        if old is not None and old.claim.task != claim.task and self._holds(robot, old.claim.task):
            self._free(old.claim.task, keep_price=True)  # it moved on
        self.reports[robot] = _Report(version, claim)
        self._raise(claim.most)
        task = self.tasks.get(claim.task) if claim.task is not None else None
        if claim.task is None or claim.task.origin != self.origin:
            return True  # claims something elsewhere, or nothing
        if task is None or robot not in task.candidates:
            self.owed.add(robot)  # closed, or not for it: it must choose again
            return True
        price, holder = self.top.get(task.id, (0.0, None))
        if holder is None:
            wins = claim.bid >= price
        else:
            wins = claim.bid > price or (claim.bid == price and robot <= holder)
        if wins:
            self.top[task.id] = (claim.bid, robot)
            if holder is not None and holder != robot:
                self.owed.add(holder)
            self.owed.discard(robot)
        else:
            self.owed.add(robot)
        return True

    def _raise(self, most: float) -> None:
        """A claim bounded by the outside option it knew: robots that claimed nothing
        below a lower ceiling are told the new one (it rises a few times per task set)."""
        if not math.isfinite(most) or most * (1 + CEILING_MARGIN) + 1e-3 <= self.ceiling:
            return
        self.ceiling = most * (1 + CEILING_MARGIN) + 1e-3
        self.owed |= {r for r, rep in self.reports.items() if rep.claim.task is None}

    def board(self, robot: str) -> Board:
        """The board for ``robot`` (and it is no longer owed one)."""
        self.owed.discard(robot)
        self._seq += 1
        report = self.reports.get(robot)
        heard = report.claim.stamp if report is not None else 0
        prices = tuple((t, *self.top.get(t, (0.0, None))) for t in self.tasks)
        return Board(self.origin, self.version, self._seq, heard, prices, self.ceiling)

    # -- agreement -----------------------------------------------------------------------
    def holders(self) -> dict[ExecutionId, Claim]:
        """Each open task's holder's claim (its cost is what the holder reported)."""
        out: dict[ExecutionId, Claim] = {}
        for task, (_price, holder) in self.top.items():
            report = self.reports.get(holder) if holder is not None else None
            if report is not None and report.claim.task == task:
                out[task] = report.claim
        return out

    def candidates(self) -> set[str]:
        """Live members that may take one of our open tasks."""
        out: set[str] = set()
        for t in self.tasks.values():
            out |= t.candidates
        return out & self.members

    def settled(self, robot: str) -> bool:
        report = self.reports.get(robot)
        if report is None or report.version != self.version or robot in self.owed:
            return False
        task = report.claim.task
        return task not in self.tasks or self._holds(robot, task)

    def converged(self) -> bool:
        """Every candidate not under suspicion has seen our task set and holds one or
        wants none of ours."""
        return not self.waiting_for()

    def waiting_for(self) -> frozenset[str]:
        """The candidates agreement waits for (never a suspect)."""
        return self.unsettled() - self.suspected

    def unsettled(self) -> frozenset[str]:
        """Every candidate not settled, suspects included (they are still retried)."""
        return frozenset(r for r in self.candidates() if not self.settled(r))
