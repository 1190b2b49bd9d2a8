"""Consensus allocation: the ``consensus`` strategy, with no auctioneer collecting bids.

Every robot runs a :class:`ConsensusAssigner`. An origin offers its pending capability
executions to the team; each robot prices them itself (the bids of
:class:`~btcap.team.runtime.executor.ExecutorSide`) and runs its part of the auction
algorithm (:mod:`btcap.team.core.consensus`): it bids for the task where its cost plus the
task's price is least, and only the task's origin, which keeps the prices of its own
tasks (:mod:`btcap.team.core.market`), hears the bid. Robots that were outbid, or bid on
stale prices, are sent the new prices and bid again; when every candidate holds a task or
wants none, or after ``window_s`` without agreement, the origin awards each task to its
holder, confirmed as in the auction (award -> accept/decline, then leases), so a task
never runs twice even if the views still differed.

When to use it: a team where no robot should decide for the others (each chooses its own
task from its own costs, which never leave it), where several robots hold mission trees
and would otherwise award the same robot from separate auctions, or whose links are flaky
(a lost member's bids simply vanish and what it held is auctioned again). It comes within
1 % of the optimum's total cost (one task per robot), in a few messages per robot.
"""

from __future__ import annotations

import asyncio
import itertools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import msgspec

from btcap.actors import Supervision, TimeSource, handler, within
from btcap.team.allocation.award import offer
from btcap.team.allocation.own_costs import OwnCosts
from btcap.team.allocation.strategy import (
    Allocator,
    AuctionRecord,
    AuctionWatcher,
    ConsensusStats,
    Pricer,
    TeamView,
)
from btcap.team.core.auction import AuctionOutcome
from btcap.team.core.award import AwardRound, bounded
from btcap.team.core.consensus import Board, Claim, Consensus, Report, Task
from btcap.team.core.fence import speedup_of
from btcap.team.core.members import TeamEvent
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Bid,
    ConsensusClaim,
    ConsensusPrices,
    ConsensusTasks,
    OpenTask,
)
from btcap.transports import Address
from btcap.transports.log import get_logger, worth_logging

__all__ = ["ConsensusAssigner", "ConsensusStats"]

log = get_logger(__name__)


@dataclass(slots=True)
class _Pending:
    id: AuctionId  # what its awards and reports are filed under
    task: AssignmentTask
    agreed: asyncio.Event
    why: dict[str, str]


class ConsensusAssigner(Allocator):
    """One robot's part of consensus allocation; see the module docstring. ``team`` is the
    robot's membership, ``pricer`` prices tasks for it (its executor side); without
    them it knows no members and claims nothing."""

    PATH = "consensus"
    #: A peer's bad message must never stop a robot's allocation.
    supervision = Supervision.RESUME

    def __init__(
        self,
        robot: str,
        *,
        window_s: float = 1.0,
        award_timeout_s: float = 0.5,
        max_tasks: int = 256,
        team: TeamView | None = None,
        pricer: Pricer | None = None,
    ) -> None:
        super().__init__()
        self.robot = robot
        self.team = team
        self.pricer = pricer
        self.window_s = window_s
        self.award_timeout_s = award_timeout_s
        self.core: Consensus[OpenTask] = Consensus(robot, max_tasks=max_tasks)
        self.stats: ConsensusStats = ConsensusStats()
        self._pending: dict[ExecutionId, _Pending] = {}
        self._impls: dict[str, str] = {}  # the implementation of each robot's claim
        self._own = OwnCosts(robot, pricer)
        self._said_version = 0  # the version of our tasks the team was told
        self._seq = itertools.count(1)
        self._ids = itertools.count(1)
        self._unsubscribe: Callable[[], None] | None = None
        self._behind: set[str] = set()  # members missing our open tasks
        self._scheduled = False
        self._watchers: list[AuctionWatcher] = []
        self._hello: set[str] = set()
        self._forgot: set[str] = set()  # members we lost (if they come back, say hello)

    def watch(self, watcher: AuctionWatcher) -> Callable[[], None]:
        """Report each task's allocation to ``watcher`` as it opens and ends, as the
        auction reports its auctions (for monitors); returns an unsubscribe."""
        self._watchers.append(watcher)
        return lambda: self._watchers.remove(watcher) if watcher in self._watchers else None

    def _report(self, record: AuctionRecord) -> None:
        for watcher in list(self._watchers):
            try:
                watcher(record)
            except Exception as exc:  # a monitor's bug must not stop allocation
                log.error("consensus.watcher_failed", robot=self.robot, exc_info=exc)

    # -- life cycle and team ----------------------------------------------------------
    def on_start(self) -> None:
        team = self.team
        if team is not None:
            self._unsubscribe = team.subscribe(self._on_team)
            for robot in sorted(team.alive()):
                self.core.join(robot)

    def on_stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event is TeamEvent.JOINED:
            self.core.join(robot)
            self._behind.add(robot)  # it needs our open tasks, changed or not
            if robot in self._forgot:  # we lost it: if it has tasks we forgot, it must say
                self._hello.add(robot)
        elif event in (TeamEvent.LEFT, TeamEvent.FAILED):
            self.core.lose(robot)
            self._impls.pop(robot, None)
            self._behind.discard(robot)
            if len(self._forgot) < self.core.max_members:
                self._forgot.add(robot)
        elif event in (TeamEvent.FREED, TeamEvent.CHANGED):
            self._own.clear()  # preconditions may be met now
        self._soon()  # (SUSPECTED: each step reads the suspects; a suspicion's end has no event)

    # -- the strategy -----------------------------------------------------------------
    async def assign(self, task: AssignmentTask) -> Assigned | Unassigned:
        clock = self.system.clock
        auction = AuctionId(self.robot, next(self._ids), task.execution.incarnation)
        mine = _Pending(auction, task, asyncio.Event(), {})
        self._pending[task.execution] = mine
        self.stats.auctions += 1
        opened = AuctionRecord(mine.id, task, clock.now())
        self._report(opened)
        won: Assigned | Unassigned | None = None
        spec = OpenTask(
            task.execution,
            task.interface,
            task.identity,
            dict(task.inputs),
            sorted(task.candidates),
            task.holder,
            task.holder_robot,
            task.margin,
            speedup_of(clock),
        )
        self.core.open(Task(task.execution, task.candidates, spec))
        try:
            while True:
                self._soon()
                if not self.core.converged():
                    await self._agreement(mine, clock)
                if self.core.converged():
                    self.stats.early_closes += 1
                won = await self._award(mine)
                if won is not None:
                    return won
        finally:
            if self._watchers:
                self._report(self._record(mine, opened, won))
            del self._pending[task.execution]
            self.core.close(task.execution)
            self._soon()

    def _record(
        self, mine: _Pending, opened: AuctionRecord, won: Assigned | Unassigned | None
    ) -> AuctionRecord:
        """How a task's allocation ended, for watchers (``won`` None: cancelled)."""
        outcome = None
        if won is not None:
            ranking = []
            if isinstance(won, Assigned):
                ranking = [Bid(mine.id, won.robot, won.cost, won.implementation)]
            silent = self.core.waiting_for() & mine.task.candidates
            outcome = AuctionOutcome(ranking, dict(mine.why), silent)
        now = self.system.clock.now()
        return AuctionRecord(mine.id, mine.task, opened.opened, now, outcome, won)

    async def _agreement(self, mine: _Pending, clock: TimeSource) -> None:
        """Until the team agrees or ``window_s`` passes; silent peers are told again at a
        quarter of the window (a message may have been lost)."""
        for _ in range(4):
            mine.agreed.clear()
            if self.core.converged():
                return
            if await within(clock, self.window_s / 4, mine.agreed.wait()) is not None:
                return
            self._retry()

    async def _award(self, mine: _Pending) -> Assigned | Unassigned | None:
        """Award the task to its winner; None: it declined, so agree again without it."""
        task = mine.task
        win = self.core.winners().get(task.execution)
        if win is None or win.robot == task.holder_robot:
            self.stats.unassigned += 1
            why = dict(mine.why)
            for robot in task.candidates - why.keys():
                why[robot] = "kept its work" if robot == task.holder_robot else "no claim"
            return Unassigned(why)
        if task.reserve is not None and win.cost >= task.reserve:
            self.stats.unassigned += 1
            return Unassigned({win.robot: f"bid {win.cost:g} not below {task.reserve:g}"})
        bid = Bid(mine.id, win.robot, win.cost, self._implementation(win))
        award = AwardRound(mine.id, task, [bid], mine.why)
        won = await offer(self, award, self.award_timeout_s, self.stats, log, event="consensus")
        if won is None:  # declined or silent: agree again without it
            self.core.restrict(task.execution, win.robot)
        return won

    def _implementation(self, win: Claim) -> str:
        if win.robot == self.robot:
            return self._own.implementation(win.task) if win.task is not None else ""
        return self._impls.get(win.robot, "")

    # -- one step: price, bid, tell ------------------------------------------------------
    def _soon(self) -> None:
        """Step once this turn of the event loop is over: what arrives meanwhile is merged
        first and goes out in one message per robot (a round of the auction), and the
        tasks a tree asks for in one tick are offered together."""
        if not self._scheduled:
            self._scheduled = True
            asyncio.get_running_loop().call_soon(self._step)

    def _step(self) -> None:
        self._scheduled = False
        if self._system is None or not self.system.running:
            return
        self.core.suspect(self.team.suspected() if self.team is not None else frozenset())
        reports, boards = self.core.step(self._own.costs(self.core.tasks()))
        if self.core.claim.task is not None and self.pricer is not None:
            self.pricer.claimed(self.core.claim.task)  # its award is one we asked for
        self._count()
        if self.core.converged():
            for p in self._pending.values():
                p.agreed.set()
        told = self.core.members - {self.robot}
        if self.core.version != self._said_version:
            self._said_version = self.core.version
            self._offer(sorted(told))
        else:
            self._offer(sorted(self._behind & told))
        self._behind.clear()
        for report in reports:
            self._hello.discard(report.origin)
            self._claim_to(report)
        for robot in sorted(self._hello & told):  # tell a (re)joined member where we are
            self._claim_to(Report(robot, self.core.claim, 0))
        self._hello.clear()
        for robot, board in boards:
            self._prices_to(robot, board)

    def _send(self, robot: str, msg: ConsensusTasks | ConsensusClaim | ConsensusPrices) -> None:
        if self._system is None or not self.system.running:
            return
        self.system.tell(Address(robot, self.PATH), msg, sender=self.address)
        self.stats.messages += 1

    def _offer(self, robots: Iterable[str]) -> None:
        """Tell ``robots`` our open tasks (none: nothing to tell; a robot that knew some
        learns they closed when it bids for one)."""
        robots = list(robots)
        if robots and self.core.own_tasks():
            tasks = [  # with the candidates left (a robot that declined is not one)
                msgspec.structs.replace(t.spec, candidates=sorted(t.candidates))
                for t in self.core.own_tasks()
            ]
            offer = ConsensusTasks(self.robot, self.core.version, tasks)
            for robot in robots:
                self._send(robot, offer)

    def _claim_to(self, report: Report) -> None:
        """Tell a task's origin our claim (and why we cannot bid for its other tasks)."""
        claim = report.claim
        why = self._own.why(report.origin)
        impl = self._implementation(claim) if claim.task is not None else ""
        cost = claim.cost if claim.task is not None else 0.0
        says = ConsensusClaim(
            self.robot,
            next(self._seq),
            claim.stamp,
            claim.task,
            cost,
            impl,
            [],
            why,
            claim.bid,
            claim.most,
            report.version,
        )
        self._send(report.origin, says)

    def _prices_to(self, robot: str, board: Board) -> None:
        prices = ConsensusPrices(
            self.robot, board.version, board.seq, board.heard, list(board.prices), board.ceiling
        )
        self._send(robot, prices)

    def _retry(self) -> None:
        """Silent candidates (a message may have been lost): the task set to those that
        have not reported on it, the prices to those that must bid again."""
        offer, boards = self.core.retry()
        self._offer(offer)
        for robot, board in boards:
            self._prices_to(robot, board)

    def _count(self) -> None:
        """Report what the core refused or dropped since last time, at a falling rate."""
        for name in ("refused", "dropped"):
            now, before = getattr(self.core, name), getattr(self.stats, name)
            if now > before:
                setattr(self.stats, name, now)
                if worth_logging(now):
                    log.warning(f"consensus.{name}", robot=self.robot, count=now)

    # -- what peers say ---------------------------------------------------------------
    def _member(self, sender: str) -> bool:
        team = self.team
        if sender not in self.core.members and team is not None and sender in team.alive():
            self.core.join(sender)  # its first word came before its heartbeat's news
        return sender in self.core.members

    @handler
    def on_tasks(self, msg: ConsensusTasks) -> None:
        sender = self.sender
        if msg.robot != sender:
            self.core.refuse()
        elif self._member(sender):
            tasks = (Task(t.execution, frozenset(t.candidates), t) for t in msg.tasks)
            self.core.offer(sender, msg.version, tasks)
        self._soon()

    @handler
    def on_claim(self, msg: ConsensusClaim) -> None:
        sender = self.sender
        if not self._member(sender):
            return  # a stranger, or a member we lost: its state is not kept
        claim = Claim(
            msg.robot,
            msg.stamp,
            msg.task,
            msg.cost if msg.task else math.inf,
            msg.bid,
            msg.most if math.isfinite(msg.most) else 0.0,
        )
        if self.core.hear(sender, claim, msg.seen) and msg.task is not None:
            self._impls[sender] = msg.implementation
        if msg.seen < self.core.version and sender in self.core.market.candidates():
            self._behind.add(sender)  # it speaks from an older task set: it missed ours
        for execution, why in msg.why[: self.core.max_tasks]:
            p = self._pending.get(execution)
            if p is not None and sender in p.task.candidates:
                p.why[sender] = bounded(why)
        self._soon()

    @handler
    def on_prices(self, msg: ConsensusPrices) -> None:
        sender = self.sender
        if msg.robot != sender:
            self.core.refuse()
        elif self._member(sender):
            prices = tuple(msg.prices[: self.core.max_tasks])
            board = Board(sender, msg.version, msg.seq, msg.heard, prices, msg.ceiling)
            self.core.price(board)
        self._soon()
