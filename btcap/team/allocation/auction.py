"""The single-item auction: the allocator of the batch strategies (``auction``,
``sequential``, ``optimal``, ``arrival`` and any
:class:`~btcap.team.allocation.strategies.BatchStrategy`)."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import itertools
from collections import deque
from collections.abc import Callable

from btcap.actors import Supervision, SystemClosed, handler, within
from btcap.team.allocation.award import offer
from btcap.team.allocation.strategy import (
    Allocator,
    AuctionRecord,
    AuctionStats,
    AuctionWatcher,
    TeamView,
)
from btcap.team.capabilities.capability import ASSIGNER_PATH
from btcap.team.core.auction import Auction, AuctionOutcome
from btcap.team.core.award import AwardRound
from btcap.team.core.fence import speedup_of
from btcap.team.core.members import TeamEvent
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned, against_holder
from btcap.team.core.turns import AUCTION, AwardQueue, BatchPolicy, PlanJob
from btcap.team.ids import AuctionId
from btcap.team.messages import Bid, CallForBids, NoBid
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

log = get_logger(__name__)


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
    lost. On a real clock a batch of more than one auction is planned in a worker thread
    (a planning policy's CPU, milliseconds to seconds for a big batch, must not hold the
    event loop); a batch of one, most auctions, is planned at once. On a virtual clock
    every plan is made at once (time does not pass meanwhile, and runs reproduce).
    """

    PATH = "auctioneer"
    exchanges = True
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
        self._extended = bool(getattr(policy, "extended", False))
        self.team = team
        self.window_s = window_s
        self.award_timeout_s = award_timeout_s
        self.stats = AuctionStats()
        self._open: dict[AuctionId, tuple[Auction, asyncio.Event]] = {}
        self._queue = AwardQueue(policy)  # the closed auctions' turns to award
        self._turns: dict[AuctionId, asyncio.Event] = {}  # set when its turn comes
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
        self._queue.off_loop = self.system.clock.to_wall(1.0) > 0  # a real clock
        if self.team is not None:
            self._unsubscribe = self.team.subscribe(self._on_team)

    def on_stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        """A robot lost or suspected: no open auction waits for it any longer (a
        suspect's answer is still taken if it comes), so none holds its batch either."""
        if event in (TeamEvent.LEFT, TeamEvent.FAILED, TeamEvent.SUSPECTED):
            now = self.system.clock.now()
            for auction, done in self._open.values():
                auction.member_lost(robot)
                if auction.closed(now):
                    done.set()

    async def assign(self, task: AssignmentTask) -> Assigned | Unassigned:
        system = self.system
        clock = system.clock
        # The auctioneer is the execution's origin: its auctions share its incarnation.
        auction_id = AuctionId(self.robot, next(self._ids), task.execution.incarnation)
        auction = Auction(auction_id, task.interface, task.candidates, clock.now() + self.window_s)
        if self.team is not None:  # a suspect may bid, but nobody waits for it
            auction.excuse(self.team.suspected() & task.candidates - {self.robot})
        done = asyncio.Event()
        self._open[auction_id] = (auction, done)
        self._queue.opened(auction_id, auction.invited)
        self.stats.auctions += 1
        opened_at = clock.now()  # a watcher's record is made only for a watcher
        if self._watchers:
            self._report(AuctionRecord(auction_id, task, opened_at))
        try:
            cfb = CallForBids(
                auction_id,
                task.interface,
                task.identity,
                dict(task.inputs),
                task.holder,
                task.handing,
                # time-extended: busy robots say what a new task would cost them later
                self._extended and task.holder is None and task.handing is None,
                speedup_of(clock),
            )
            me = self.address
            for robot in sorted(task.candidates):
                system.tell(Address(robot, ASSIGNER_PATH), cfb, sender=me)
            if not auction.closed(clock.now()):
                await self._window(done)
        except BaseException:
            del self._open[auction_id]
            self._queue.dropped(auction_id)
            self._next_turn()  # others may have waited for this one
            if self._watchers:
                self._report(AuctionRecord(auction_id, task, opened_at, clock.now()))
            raise
        if auction.answered_all:
            self.stats.early_closes += 1
        outcome = auction.outcome()
        self.outcomes.append(outcome)
        task = against_holder(task, outcome)
        turn = asyncio.Event()
        del self._open[auction_id]
        self._queue.closed(auction_id, outcome, task.reserve)
        self._turns[auction_id] = turn
        won: Assigned | Unassigned | None = None
        award: AwardRound | None = None
        try:
            self._next_turn()
            await turn.wait()
            award = self._queue.round(auction_id, task)
            if self.team is not None:  # a suspect's bid counts, but is asked last
                award.defer(self.team.suspected())
            won = await offer(
                self, award, self.award_timeout_s, self.stats, log, event="auction", min_wall=0.05
            )
            if won is None:
                self.stats.unassigned += 1
                won = award.result()
            else:
                self._queue.took(won.robot)
                held = [b.cost for b in outcome.ranking if b.robot == task.holder_robot]
                if held:
                    won = dataclasses.replace(won, held=held[0])
            return won
        finally:
            if self._watchers:  # ``won`` None: cancelled while awarding
                passed = {} if award is None else dict(award.reasons)
                end = AuctionRecord(auction_id, task, opened_at, clock.now(), outcome, won, passed)
                self._report(end)
            self._turns.pop(auction_id, None)
            self._queue.finished(auction_id)
            self._next_turn()

    async def _window(self, done: asyncio.Event) -> None:
        """Until every invited robot answered (``done``) or the window passed. On a real
        clock a loop timer ends the wait: ``within``'s timeout context costs more, once
        a round; on a virtual one, ``within`` as ever (the order runs reproduce by)."""
        wall = self.system.clock.to_wall(self.window_s)
        if wall <= 0:
            await within(self.system.clock, self.window_s, done.wait())
            return
        timer = asyncio.get_running_loop().call_later(wall, done.set)
        try:
            await done.wait()
        finally:
            timer.cancel()

    def _next_turn(self) -> None:
        """Let the closed auction whose turn it is award (see :class:`AwardQueue`)."""
        turn = self._queue.next_turn()
        if turn is not None:
            self._turns.pop(turn).set()
        elif (job := self._queue.planning()) is not None:
            with contextlib.suppress(SystemClosed):  # leaving: its auctions end unawarded
                self.system.start_task(self._plan(job), name=f"plan of {self.robot}'s batch")

    async def _plan(self, job: PlanJob) -> None:
        """Plan ``job`` in a worker thread, then let the batch award. A policy that
        raises is logged and the batch awards without a plan."""
        try:
            robots = await asyncio.to_thread(self.policy.plan, job.bids, job.taken)
        except Exception as exc:
            log.error("auction.plan_failed", robot=self.robot, exc_info=exc)
            robots = None
        self._queue.planned(job, robots)
        self._next_turn()

    @handler(Bid, NoBid)
    def on_answer(self, msg: Bid | NoBid) -> None:
        entry = self._open.get(msg.auction)
        if entry is None:
            return  # late: the auction has closed
        auction, done = entry
        auction.offer(msg, sender=self.sender)
        if auction.answered_all:
            done.set()
