"""The order in which a batch of closed auctions awards, and to whom (sans-IO).

An auctioneer holds the closed auctions of a batch (those that ran at the same time for
the same robots, an :class:`AwardQueue`) until none still collecting bids competes for
their robots; a :class:`BatchPolicy` then says whether it plans the batch (a robot for
each auction) and which auction awards next, one at a time. The four built-in policies
are the strategies of :mod:`btcap.team.core.planning`; a third-party strategy can bring
its own (see :class:`btcap.team.allocation.strategies.BatchStrategy`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence, Set
from dataclasses import dataclass
from typing import Protocol

from btcap.team.core.auction import AuctionOutcome
from btcap.team.core.award import AwardRound, passed_over
from btcap.team.core.planning import PLANNING_MODULES, optimal_plan, regret, sequential_plan
from btcap.team.core.task import AssignmentTask
from btcap.team.ids import AuctionId
from btcap.team.messages import Bid

__all__ = [
    "ARRIVAL",
    "AUCTION",
    "OPTIMAL",
    "SEQUENTIAL",
    "AwardQueue",
    "BatchPolicy",
    "PlanJob",
    "Planned",
]

#: A robot for each task of the batch, in order (None: no robot for it).
Plan = Sequence[str | None]


class BatchPolicy(Protocol):
    """How a batch of closed auctions is awarded.

    ``batches`` False: each auction awards as it closes, oldest first, without waiting
    for competitors still open. ``plan`` is asked once per batch (when no auction of it
    has a plan yet) with each auction's awardable bids, cheapest first, and the robots
    already ``taken`` in the batch; it returns a robot per auction, or None to award
    without a plan. ``first`` gets each waiting auction's bids still free, its planned
    robot first, and returns the index of the one that awards next.

    A policy may also say ``extended = True`` (time-extended bids; absent means False):
    its calls for bids ask busy robots what each new task would cost them after the
    work they hold, and ``plan`` gets those bids (``Bid.later``) after each
    auction's awardable ones. They are never awarded: a plan naming such a robot is
    awarded to the cheapest free bidder instead.

    ``plan`` of a batch of more than one auction may run in a worker thread (on a real
    clock: see :attr:`AwardQueue.off_loop`), so it must be a pure function of its
    arguments. A policy may name in ``modules`` (absent: none) what its ``plan`` imports
    when it first plans such a batch (numpy, scipy); a robot imports them in a worker
    thread when it first attaches a mission, so no import ever holds its event loop.
    """

    @property
    def batches(self) -> bool: ...

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None: ...

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int: ...


def _argmin(ordered: Sequence[Sequence[Bid]], key: Callable[[Sequence[Bid]], object]) -> int:
    """The index of the smallest key; ties: the lowest index (the oldest auction)."""
    return min(range(len(ordered)), key=lambda i: key(ordered[i]))  # type: ignore[arg-type,return-value]


def _best(bids: Sequence[Bid]) -> tuple[float, str]:
    """The bid an auction would award first (its planned robot's, if any)."""
    return (bids[0].cost, bids[0].robot) if bids else (math.inf, "")


class _ByRegret:
    """``auction``: no plan; the auction that would lose most by waiting goes first."""

    batches = True

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return None

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return _argmin(ordered, regret)


class Planned:
    """A planning policy: ``planner`` gives the batch's robots; the cheapest award first.
    ``extended``: the planner is also given time-extended bids; ``modules``: what the
    planner imports on first use (see :class:`BatchPolicy`)."""

    batches = True

    def __init__(
        self,
        planner: Callable[[Sequence[Sequence[Bid]], Set[str]], Plan],
        *,
        extended: bool = False,
        modules: tuple[str, ...] = (),
    ) -> None:
        self.planner = planner
        self.extended = extended
        self.modules = modules

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return self.planner(bids, taken)

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return _argmin(ordered, _best)


class _ByArrival:
    """``arrival``: each auction awards as it closes."""

    batches = False

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return None

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return 0


AUCTION: BatchPolicy = _ByRegret()
SEQUENTIAL: BatchPolicy = Planned(sequential_plan, modules=PLANNING_MODULES)
OPTIMAL: BatchPolicy = Planned(optimal_plan, extended=True, modules=PLANNING_MODULES)
ARRIVAL: BatchPolicy = _ByArrival()


@dataclass(frozen=True, slots=True, eq=False)
class PlanJob:
    """A batch to plan away from the caller (:meth:`AwardQueue.planning`): the policy's
    ``plan(bids, taken)``, whose result goes back through :meth:`AwardQueue.planned`."""

    bids: list[list[Bid]]
    taken: frozenset[str]
    closed: tuple[object, ...]  # the batch as it was: a plan for another one is dropped


@dataclass(slots=True, eq=False)
class _Closed:
    """A closed auction waiting for its turn to award."""

    auction: AuctionId
    outcome: AuctionOutcome
    reserve: float | None
    plan: str | None = None  # a planning policy's robot for it
    planned: bool = False  # a plan was made for it (``plan`` None: it waits)

    def bids(self, taken: Set[str]) -> list[Bid]:
        """What may be awarded, best first: the planned robot, then the cheapest free
        (a busy robot that could queue it only if planned); nothing for a task the plan
        leaves waiting."""
        bids = [b for b in self.outcome.awardable(self.reserve) if b.robot not in taken]
        if self.planned:
            if self.plan is None:
                return []
            bids = [b for b in bids if b.robot == self.plan or not b.after]
        return sorted(bids, key=lambda b: b.robot != self.plan)


class AwardQueue:
    """One auctioneer's auctions between their call for bids and their award: which
    closed auction awards next (:meth:`next_turn`, through its ``policy``), one at a
    time, and the robots ``taken`` by the batch so far (they bid as if idle, so they
    wait for the next batch). The caller tells it each step, with no clock of its own.

    With :attr:`off_loop` set, a batch of more than one auction is not planned in
    :meth:`next_turn`: the caller takes it from :meth:`planning`, plans it where it
    likes (a worker thread: a big batch costs milliseconds to seconds of CPU) and hands
    the plan back to :meth:`planned`; no auction of the batch awards meanwhile. A batch
    of one is planned at once (a single task needs no matrix).
    """

    def __init__(self, policy: BatchPolicy, *, off_loop: bool = False) -> None:
        self.policy = policy
        #: Whether batches of more than one auction are planned by the caller.
        self.off_loop = off_loop
        self._job: PlanJob | None = None  # a batch being planned by the caller
        self._job_out = False  # ... and handed out by :meth:`planning`
        #: Robots that accepted a task of this batch (forgotten when the batch is done).
        self.taken: set[str] = set()
        self._open: dict[AuctionId, frozenset[str]] = {}  # collecting bids: who is invited
        self._closed: list[_Closed] = []  # waiting for their turn, oldest first
        self._awarding: _Closed | None = None

    @property
    def waiting(self) -> list[AuctionId]:
        """The closed auctions waiting for their turn, oldest first."""
        return [c.auction for c in self._closed]

    @property
    def awarding(self) -> AuctionId | None:
        """The auction whose turn it is (until :meth:`finished`)."""
        return None if self._awarding is None else self._awarding.auction

    def opened(self, auction: AuctionId, invited: frozenset[str]) -> None:
        """An auction called for bids from ``invited``."""
        self._open[auction] = invited

    def dropped(self, auction: AuctionId) -> None:
        """An auction was given up while still collecting bids."""
        self._open.pop(auction, None)

    def closed(self, auction: AuctionId, outcome: AuctionOutcome, reserve: float | None) -> None:
        """An auction closed with ``outcome``; it awards only bids below ``reserve``.
        It leaves the open auctions and joins the closed ones in one step: a closed
        auction never takes its turn while a competitor is between the two."""
        self._open.pop(auction, None)
        self._closed.append(_Closed(auction, outcome, reserve))

    def next_turn(self) -> AuctionId | None:
        """The closed auction that awards now, or None: one is awarding, none is
        waiting, or (batching policies) an auction still collecting bids invited a robot
        the waiting ones bid with (its bids may be cheaper: wait for it to close)."""
        if self._awarding is not None or not self._closed:
            return None
        policy = self.policy
        if not policy.batches:
            nxt = self._closed[0]
        else:
            wanted = {b.robot for c in self._closed for b in c.outcome.ranking}
            if any(wanted & invited for invited in self._open.values()):
                return None
            if not any(c.planned for c in self._closed):
                if self._job is not None:
                    return None  # its plan is being made
                batch = [c.bids(self.taken) for c in self._closed]
                if getattr(policy, "extended", False):
                    batch = [
                        b + c.outcome.later() for b, c in zip(batch, self._closed, strict=True)
                    ]
                if self.off_loop and len(batch) > 1:
                    self._job = PlanJob(batch, frozenset(self.taken), tuple(self._closed))
                    return None
                self._apply(policy.plan(batch, self.taken))
            waiting = self._closed
            # one waiting (most batches): it goes first whatever its bids
            nxt = (
                waiting[0]
                if len(waiting) == 1
                else waiting[policy.first([c.bids(self._held(c)) for c in waiting])]
            )
        self._closed.remove(nxt)
        self._awarding = nxt
        return nxt.auction

    def planning(self) -> PlanJob | None:
        """The batch :meth:`next_turn` left to the caller to plan (see :attr:`off_loop`),
        once: None if there is none, or it was handed out already."""
        if self._job is None or self._job_out:
            return None
        self._job_out = True
        return self._job

    def planned(self, job: PlanJob, robots: Plan | None) -> bool:
        """The plan of ``job`` (None: award without one, as a policy may say). Taken only
        if the batch is still the one planned (no auction joined or left it, no robot
        was taken since): else dropped, and :meth:`next_turn` asks for a new plan.
        Call :meth:`next_turn` after it."""
        if job is not self._job:
            return False
        self._job, self._job_out = None, False
        if job.closed != tuple(self._closed) or job.taken != self.taken:
            return False
        self._apply(robots)
        return True

    def _apply(self, robots: Plan | None) -> None:
        """Give each closed auction its planned robot (``robots`` None: no plan)."""
        for closed, robot in zip(self._closed, robots or [None] * len(self._closed), strict=True):
            closed.plan, closed.planned = robot, robots is not None

    def round(self, auction: AuctionId, task: AssignmentTask) -> AwardRound:
        """The award of the auction whose turn it is: its free bids, the planned robot
        first, and why the others were passed over."""
        closed = self._awarding
        if closed is None or closed.auction != auction:
            raise ValueError(f"auction {auction} is not the one awarding")
        held = self._held(closed)
        reasons = passed_over(closed.outcome, closed.reserve, held)
        if closed.planned and closed.plan is None:
            for b in closed.outcome.awardable(closed.reserve):
                reasons.setdefault(b.robot, "busy with the plan's other work: this task waits")
        return AwardRound(auction, task, closed.bids(held), reasons)

    def _held(self, closed: _Closed) -> Set[str]:
        """The robots ``closed`` may not be awarded: those taken in the batch and those
        the plan gives another auction still waiting (a task the plan leaves waiting
        does not take a robot planned for another, nor does a declined award)."""
        planned = {c.plan for c in self._closed if c is not closed and c.plan is not None}
        return self.taken | planned if planned else self.taken

    def took(self, robot: str) -> None:
        """``robot`` accepted a task of this batch."""
        self.taken.add(robot)

    def finished(self, auction: AuctionId) -> None:
        """An auction closed is done: awarded, or given up while waiting or awarding.
        The batch ends with its last auction."""
        self._closed = [c for c in self._closed if c.auction != auction]
        if self._awarding is not None and self._awarding.auction == auction:
            self._awarding = None
        if not self._closed:
            self.taken.clear()
