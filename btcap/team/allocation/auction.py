"""The single-item auction: the allocator of the batch strategies (``auction``,
``sequential``, ``optimal``, ``arrival`` and any
:class:`~btcap.team.allocation.strategies.BatchStrategy`)."""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from btcap.actors import (
    ActorError,
    AskTimeout,
    Supervision,
    handler,
    within,
)
from btcap.team.allocation.strategy import (
    Allocator,
    AuctionRecord,
    AuctionStats,
    AuctionWatcher,
    TeamView,
)
from btcap.team.capabilities.capability import ASSIGNER_PATH
from btcap.team.core.auction import REASON_CHARS, Auction, AuctionOutcome
from btcap.team.core.members import TeamEvent
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned, against_holder
from btcap.team.core.turns import AUCTION, BatchPolicy
from btcap.team.ids import AuctionId
from btcap.team.messages import Award, AwardReply, Bid, CallForBids, CancelExecution, NoBid
from btcap.transports import Address
from btcap.transports.log import get_logger

__all__ = [
    "Assigned",
    "AssignmentTask",
    "AuctionRecord",
    "AuctionStats",
    "AuctionWatcher",
    "SingleItemAuction",
    "Unassigned",
]

log = get_logger("btcap.team.assignment")


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


class SingleItemAuction(Allocator):
    """Call for bids, close early, award the cheapest bidder, fall through on declines.

    The auctioneer's own robot is invited like any other (it bids in its own auction).
    The auction closes when every invited robot still alive has bid or declined, or when
    ``window_s`` clock seconds have passed. Awards are asks: a winner that became busy
    declines and the award goes to the next-best bid. A task with a ``reserve`` is
    awarded only to a bid below it.

    Auctions that run at the same time for the same robots award one after the other,
    in an order (and, for the planning strategies, to robots) chosen from their bids
    together by its ``policy`` (see :mod:`btcap.team.core.turns`): a robot that comes
    free gets the task best for the team, not the one whose auction closed first.
    ``team`` (the robot's membership) closes an auction early when an invited robot is
    lost.
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
        policy: BatchPolicy = AUCTION,
        team: TeamView | None = None,
    ) -> None:
        super().__init__()
        self.robot = robot
        self.policy = policy
        self.team = team
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
        if self.team is not None:
            self._unsubscribe = self.team.subscribe(self._on_team)

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
        task = against_holder(task, outcome)
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
        policy = self.policy
        if not policy.batches:
            nxt = self._closed[0]
        else:
            wanted = {b.robot for c in self._closed for b in c.outcome.ranking}
            if any(wanted & a.invited for a, _done in self._open.values()):
                return  # its bids may be cheaper: wait for it to close
            if all(c.plan is None for c in self._closed):
                batch = [c.bids(self._taken) for c in self._closed]
                robots = policy.plan(batch, self._taken) or [None] * len(batch)
                for closed, robot in zip(self._closed, robots, strict=True):
                    closed.plan = robot
            nxt = self._closed[policy.first([c.bids(self._taken) for c in self._closed])]
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
            reasons[bid.robot] = f"declined the award: {reply.reason[:REASON_CHARS]}"
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
