"""The assignment system: an abstract strategy and the reference single-item auction."""

from __future__ import annotations

import abc
import asyncio
import dataclasses
import itertools
import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from btcap.actors import (
    Actor,
    ActorError,
    AskTimeout,
    Supervision,
    handler,
    within,
)
from btcap.team.capability import ASSIGNER_PATH
from btcap.team.core.auction import Auction, AuctionOutcome
from btcap.team.core.ids import AuctionId, ExecutionId
from btcap.team.core.planning import check_strategy, plan, regret
from btcap.team.membership import Membership, TeamEvent
from btcap.team.messages import Award, AwardReply, Bid, CallForBids, CancelExecution, NoBid
from btcap.transports import Address
from btcap.transports.log import get_logger

__all__ = [
    "Assigned",
    "AssignmentStrategy",
    "AssignmentTask",
    "AuctionRecord",
    "AuctionStats",
    "SingleItemAuction",
    "Unassigned",
]

log = get_logger("btcap.team.assignment")


@dataclass(frozen=True, slots=True)
class AssignmentTask:
    """One capability execution to place on a robot."""

    execution: ExecutionId
    interface: str
    identity: str
    inputs: Mapping[str, Any]
    candidates: frozenset[str]
    lease_s: float
    reserve: float | None = None  # award only bids cheaper than this (moving running work)
    paused: bool = False  # the winner holds the run until its first inputs
    #: Re-evaluating running work: the execution and the robot running it (it bids what
    #: finishing would cost, is never awarded, and others must beat its bid by ``margin``).
    holder: ExecutionId | None = None
    holder_robot: str | None = None
    margin: float = 0.0


@dataclass(frozen=True, slots=True)
class Assigned:
    """The robot that accepted, with the implementation it runs and its bid."""

    robot: str
    implementation: str
    cost: float


@dataclass(frozen=True, slots=True)
class Unassigned:
    """Nobody took the task, and why, robot by robot (for the log and the user)."""

    reasons: Mapping[str, str]


@dataclass(frozen=True, slots=True)
class AuctionRecord:
    """An auction as a watcher sees it: reported once when it opens (``outcome`` and
    ``result`` None) and once when it ends (both set, or ``outcome`` None if it was
    cancelled while open)."""

    id: AuctionId
    task: AssignmentTask
    opened: float
    closed: float | None = None
    outcome: AuctionOutcome | None = None
    result: Assigned | Unassigned | None = None
    #: Why robots were passed over, winner or not: declined to bid, no answer, a bid not
    #: below the reserve, the award declined or unanswered.
    passed: Mapping[str, str] = dataclasses.field(default_factory=dict)


#: Called with every :class:`AuctionRecord` an auctioneer reports.
AuctionWatcher = Callable[[AuctionRecord], None]


@dataclass(slots=True)
class AuctionStats:
    auctions: int = 0
    awarded: int = 0
    unassigned: int = 0
    declined_awards: int = 0
    early_closes: int = 0


class AssignmentStrategy(abc.ABC):
    """Chooses the executor of a capability among candidate robots."""

    @abc.abstractmethod
    async def assign(self, task: AssignmentTask) -> Assigned | Unassigned:
        """Find a robot that accepted to run ``task`` now, or say why none did."""


def _against_holder(task: AssignmentTask, outcome: AuctionOutcome) -> AssignmentTask:
    """Re-evaluation: others must beat the holder's fresh bid by the margin (the holder
    itself is never awarded its own work again)."""
    if task.holder_robot is None:
        return task
    held = next((b.cost for b in outcome.ranking if b.robot == task.holder_robot), None)
    if held is None:  # no fresh bid to compare with: the work stays where it is
        return dataclasses.replace(task, reserve=0.0)
    beat = held * (1.0 - task.margin)
    return dataclasses.replace(
        task, reserve=beat if task.reserve is None else min(task.reserve, beat)
    )


@dataclass(slots=True, eq=False)
class _Closed:
    """A closed auction waiting for its turn to award."""

    outcome: AuctionOutcome
    reserve: float | None
    turn: asyncio.Event
    plan: str | None = None  # a planning strategy's robot for it
    #: Why robots were passed over when it awarded (for watchers).
    passed: dict[str, str] = dataclasses.field(default_factory=dict)

    def bids(self, taken: set[str]) -> list[Bid]:
        """What may be awarded, best first: the planned robot, then the cheapest free."""
        bids = [b for b in self.outcome.awardable(self.reserve) if b.robot not in taken]
        return sorted(bids, key=lambda b: b.robot != self.plan)

    def best(self, taken: set[str]) -> tuple[float, str]:
        """The bid it would award first (for the order of turns)."""
        bids = self.bids(taken)
        return (bids[0].cost, bids[0].robot) if bids else (math.inf, "")


class SingleItemAuction(Actor, AssignmentStrategy):
    """Call for bids, close early, award the cheapest bidder, fall through on declines.

    The auctioneer's own robot is invited like any other (it bids in its own auction).
    The auction closes when every invited robot still alive has bid or declined, or when
    ``window_s`` clock seconds have passed. Awards are asks: a winner that became busy
    declines and the award goes to the next-best bid. A task with a ``reserve`` is
    awarded only to a bid below it.

    Auctions that run at the same time for the same robots award one after the other,
    in an order (and, for the planning strategies, to robots) chosen from their bids
    together (see :mod:`btcap.team.core.planning`): a robot that comes free gets the task
    best for the team, not the one whose auction closed first.
    """

    PATH = "auctioneer"
    #: A peer's bad answer must never stop a robot's auctioneer.
    supervision = Supervision.RESUME

    def __init__(
        self,
        robot: str,
        *,
        window_s: float = 1.0,
        award_timeout_s: float = 0.5,
        strategy: str = "auction",
    ) -> None:
        super().__init__()
        self.robot = robot
        self.strategy = check_strategy(strategy)
        self.window_s = window_s
        self.award_timeout_s = award_timeout_s
        self.stats = AuctionStats()
        self._open: dict[AuctionId, tuple[Auction, asyncio.Event]] = {}
        self._closed: list[_Closed] = []  # waiting for their turn to award
        self._awarding: _Closed | None = None
        self._taken: set[str] = set()  # robots that accepted in this batch
        #: The latest auctions' outcomes, newest last (for monitoring and tests).
        self.outcomes: deque[AuctionOutcome] = deque(maxlen=64)
        self._ids = itertools.count(1)
        self._unsubscribe: Callable[[], None] | None = None
        self._watchers: list[AuctionWatcher] = []

    def watch(self, watcher: AuctionWatcher) -> Callable[[], None]:
        """Report every auction to ``watcher`` as it opens and ends (for monitors);
        returns an unsubscribe. A watcher that raises is logged and skipped."""
        self._watchers.append(watcher)
        return lambda: self._watchers.remove(watcher) if watcher in self._watchers else None

    def _report(self, record: AuctionRecord) -> None:
        for watcher in list(self._watchers):
            try:
                watcher(record)
            except Exception as exc:
                log.error("auction.watcher_failed", robot=self.robot, exc_info=exc)

    def on_start(self) -> None:
        team = self.system.lookup(Membership.PATH)
        if isinstance(team, Membership):
            self._unsubscribe = team.subscribe(self._on_team)

    def on_stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event in (TeamEvent.LEFT, TeamEvent.FAILED):
            now = self.system.clock.now()
            for auction, done in self._open.values():
                auction.member_lost(robot)
                if auction.closed(now):
                    done.set()

    async def assign(self, task: AssignmentTask) -> Assigned | Unassigned:
        system = self.system
        clock = system.clock
        auction_id = AuctionId(self.robot, next(self._ids))
        auction = Auction(auction_id, task.interface, task.candidates, clock.now() + self.window_s)
        done = asyncio.Event()
        self._open[auction_id] = (auction, done)
        self.stats.auctions += 1
        opened = AuctionRecord(auction_id, task, clock.now())
        if self._watchers:
            self._report(opened)
        try:
            cfb = CallForBids(
                auction_id, task.interface, task.identity, dict(task.inputs), task.holder
            )
            for robot in sorted(task.candidates):
                system.tell(Address(robot, ASSIGNER_PATH), cfb, sender=self.address)
            if not auction.closed(clock.now()):
                await within(clock, self.window_s, done.wait())
        except BaseException:
            del self._open[auction_id]
            self._next_turn()  # others may have waited for this one
            if self._watchers:
                self._report(dataclasses.replace(opened, closed=clock.now()))
            raise
        if auction.answered_all:
            self.stats.early_closes += 1
        outcome = auction.outcome()
        self.outcomes.append(outcome)
        task = _against_holder(task, outcome)
        mine = _Closed(outcome, task.reserve, asyncio.Event())
        # Leaving the open auctions and joining the closed ones in one step: a closed
        # auction never takes its turn while a competitor is between the two.
        del self._open[auction_id]
        self._closed.append(mine)
        won: Assigned | Unassigned | None = None
        try:
            self._next_turn()
            await mine.turn.wait()
            won = await self._award(task, auction_id, mine)
            if isinstance(won, Assigned):
                self._taken.add(won.robot)
            return won
        finally:
            if self._watchers:  # ``won`` None: cancelled while awarding
                end = dataclasses.replace(opened, task=task, closed=clock.now(), result=won)
                self._report(dataclasses.replace(end, outcome=outcome, passed=dict(mine.passed)))
            if mine in self._closed:
                self._closed.remove(mine)
            if self._awarding is mine:
                self._awarding = None
            if not self._closed:
                self._taken.clear()
            self._next_turn()

    def _next_turn(self) -> None:
        """Let the closed auction with the cheapest free bid award, once no auction still
        collecting bids competes with the waiting ones for a robot."""
        if self._awarding is not None or not self._closed:
            return
        if self.strategy == "arrival":
            nxt = self._closed[0]
        else:
            wanted = {b.robot for c in self._closed for b in c.outcome.ranking}
            if any(wanted & a.invited for a, _done in self._open.values()):
                return  # its bids may be cheaper: wait for it to close
            if all(c.plan is None for c in self._closed):
                batch = [c.bids(self._taken) for c in self._closed]
                robots = plan(self.strategy, batch, self._taken) or [None] * len(batch)
                for closed, robot in zip(self._closed, robots, strict=True):
                    closed.plan = robot
            if self.strategy == "auction":
                nxt = min(self._closed, key=lambda c: regret(c.bids(self._taken)))
            else:
                nxt = min(self._closed, key=lambda c: c.best(self._taken))
        self._closed.remove(nxt)
        self._awarding = nxt
        nxt.turn.set()

    async def _award(
        self, task: AssignmentTask, auction_id: AuctionId, mine: _Closed
    ) -> Assigned | Unassigned:
        system = self.system
        clock = system.clock
        outcome = mine.outcome
        reasons = mine.passed
        reasons.update(outcome.declined)
        reasons.update((robot, "no answer") for robot in outcome.silent)
        for bid in outcome.ranking:
            if task.reserve is not None and bid.cost >= task.reserve:
                reasons[bid.robot] = f"bid {bid.cost:g} not below {task.reserve:g}"
            elif bid.robot in self._taken:
                reasons[bid.robot] = "took another task of the same round"
        # A robot that took a task in this batch bid as if idle: it waits for the next one.
        for bid in mine.bids(self._taken):
            award = Award(
                auction_id,
                task.execution,
                task.interface,
                bid.implementation,
                dict(task.inputs),
                task.lease_s,
                task.paused,
            )
            executor = system.ref(Address(bid.robot, ASSIGNER_PATH))
            try:
                reply = await within(
                    clock,
                    self.award_timeout_s,
                    executor.ask(award, expect=AwardReply),
                    min_wall=0.05,
                )
                if reply is None:
                    raise AskTimeout(
                        f"no reply from {executor.address} to the award "
                        f"within {self.award_timeout_s} clock s"
                    )
            except (ActorError, TypeError, asyncio.CancelledError) as exc:
                # The robot may still take the award after we gave up waiting (or were
                # cancelled): withdraw it, so the task never runs twice at once.
                executor.tell(
                    CancelExecution(task.execution, "award withdrawn"), sender=self.address
                )
                if isinstance(exc, asyncio.CancelledError):
                    raise
                log.info("auction.award_lost", auction=auction_id, robot=bid.robot, error=str(exc))
                self.stats.declined_awards += 1
                reasons[bid.robot] = f"no answer to the award ({exc})"
                continue
            if reply.accepted:
                self.stats.awarded += 1
                return Assigned(bid.robot, bid.implementation, bid.cost)
            self.stats.declined_awards += 1
            reasons[bid.robot] = f"declined the award: {reply.reason}"
            log.info(
                "auction.award_declined", auction=auction_id, robot=bid.robot, reason=reply.reason
            )
        self.stats.unassigned += 1
        return Unassigned(reasons)

    @handler(Bid, NoBid)
    def on_answer(self, msg: Bid | NoBid) -> None:
        entry = self._open.get(msg.auction)
        if entry is None:
            return  # late: the auction has closed
        auction, done = entry
        auction.offer(msg, sender=self.sender)
        if auction.answered_all:
            done.set()
