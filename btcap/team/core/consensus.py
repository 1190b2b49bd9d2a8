"""Consensus allocation as pure state: the auction algorithm run by the robots themselves.

Each robot decides alone, from its own costs and the prices it knows, which task it bids
for (Bertsekas' auction algorithm; Bertsekas and Castanon showed it converges with stale
prices and in any message order). It claims the task ``j`` with the least cost plus
price ``c_j + p_j``, bidding ``p_j + (w - v) + eps``: ``v`` that least sum, ``w`` the
second least (or the outside option), ``eps`` the slack that bounds how far from the
optimum the end can be. Each task's price is kept by its origin
(:class:`~btcap.team.core.market.Market`), which tells only the robots that must bid
again (outbid, or refused with stale prices) the new prices: a round costs each robot one
message to each origin with open tasks, and each origin one message to each robot that
lost, so the traffic per robot per round grows at most linearly with the team, and the
whole auction costs a few messages per robot, not a broadcast of every change.

Quality: the end satisfies eps-complementary slackness, so its total cost is within the
sum of the robots' eps of the optimum (one task per robot). Each robot's eps is
:data:`DELTA` times its own cheapest cost, so with as many tasks as robots the total is
within ``1 + DELTA`` of the optimum; it is at least :data:`FLOOR` times the outside
option, so a price war between robots that cost the same ends within ``1/FLOOR`` bids.

A robot beyond the tasks' number takes its outside option, claiming nothing, once every
task's cost plus price exceeds it. That option, each origin's *ceiling*, is agreed through
the protocol: a little over the dearest cost any candidate reported in its claims (the
origin's board carries it), so every task is worth taking and with robots outnumbering
tasks prices rise until the robots that would add most keep out.

Messages lost or reordered change nothing: claims carry stamps, boards sequence
numbers; a robot told its task set again, or a board older than its claim, says its
claim again (an origin retries the silent at a quarter window).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from btcap.team.core.market import CEILING_MARGIN, Board, Claim, Market, Task
from btcap.team.ids import ExecutionId

__all__ = ["DELTA", "FLOOR", "Board", "Claim", "Consensus", "Report", "Task"]

T = TypeVar("T")

#: A robot's eps: this share of its own cheapest cost (the end is within 1 + DELTA).
DELTA = 0.01
#: The least eps, as a share of the outside option: a price war between robots that
#: cost the same ends within 1/FLOOR bids.
FLOOR = 1e-3


@dataclass(frozen=True, slots=True)
class Report:
    """A claim for an origin, made having merged ``version`` of that origin's tasks."""

    origin: str
    claim: Claim
    version: int


@dataclass(slots=True)
class _Offer(Generic[T]):
    version: int
    tasks: dict[ExecutionId, Task[T]] = field(default_factory=dict)


class Consensus(Generic[T]):
    """One robot's side of consensus allocation: its bids, and as an origin, the board of
    its own tasks (:attr:`market`). ``dropped`` counts tasks over the bounds a peer sent,
    ``refused`` messages that spoke for someone else or made no sense: the shell logs
    them (the core does no I/O). Robots not (or no longer) members are not heard at all."""

    def __init__(self, robot: str, *, max_tasks: int = 256, max_members: int = 1024) -> None:
        self.robot = robot
        self.max_tasks = max_tasks
        self.max_members = max_members
        self.members: set[str] = {robot}
        self.market: Market[T] = Market(robot)
        self.claim = Claim(robot, 0)
        self.dropped = 0
        self._refused = 0
        self._offers: dict[str, _Offer[T]] = {}
        self._boards: dict[str, Board] = {}
        self._prices: dict[str, dict[ExecutionId, tuple[float, str | None]]] = {}
        self._basis: tuple[object, ...] | None = None
        self._told: dict[str, tuple[int, int]] = {}  # origin -> (stamp, version) it heard
        self._owe: set[str] = set()  # origins to tell our claim again
        self._barred: set[ExecutionId] = set()  # refused us until its task set changes
        self._forgot: set[str] = set()  # members lost: their claims to us were dropped
        self.suspected: frozenset[str] = frozenset()  # members under suspicion now

    @property
    def refused(self) -> int:
        return self._refused + self.market.refused

    def refuse(self) -> None:
        """Count a message the shell found speaking for someone else."""
        self._refused += 1

    # -- the team ---------------------------------------------------------------------
    def join(self, robot: str) -> None:
        """A member to hear from (its earlier life, if any, was forgotten when it was lost).
        One we lost is owed our board: it may still claim a task of ours that closed while
        it was lost, having told us (unheard), and only a board whose ``heard`` is below
        its claim makes it say the claim again (heavy sim-test seed 781: two robots held a
        closed task for ever, the origin having no open task to offer them)."""
        if robot not in self.members and len(self.members) < self.max_members:
            self.members.add(robot)
            self.market.join(robot)
            if robot in self._forgot:
                self._forgot.discard(robot)
                self.market.owed.add(robot)

    def lose(self, robot: str) -> None:
        """A member left or failed: its bids go (what it held is free again), and so do
        its tasks."""
        if robot == self.robot:
            return
        if robot in self.members and len(self._forgot) < self.max_members:
            self._forgot.add(robot)
        self.members.discard(robot)
        self.suspected -= {robot}
        self.market.lose(robot)
        for table in (self._offers, self._boards, self._prices, self._told):
            table.pop(robot, None)
        self._owe.discard(robot)

    def suspect(self, robots: frozenset[str]) -> None:
        """The members under suspicion of failure now (the whole set, before each step):
        as an origin, agreement waits for none of them and what one holds is auctioned
        again (:meth:`Market.suspect`); as a bidder, this robot stops bidding for a
        suspect's tasks (its claim would hold nothing if the origin is gone). Both come
        back as they were once a suspicion ends (refuted): the robot is waited for, its
        tasks are bid for again."""
        self.suspected = frozenset(robots & self.members - {self.robot})
        self.market.suspect(self.suspected)

    # -- this robot's own tasks -------------------------------------------------------
    def open(self, task: Task[T]) -> None:
        self.market.open(task)

    def close(self, task: ExecutionId) -> None:
        self.market.close(task)

    def restrict(self, task: ExecutionId, robot: str) -> None:
        """``robot`` may no longer take this robot's ``task`` (it declined the award)."""
        self.market.restrict(task, robot)

    @property
    def version(self) -> int:
        return self.market.version

    def own_tasks(self) -> list[Task[T]]:
        return list(self.market.tasks.values())

    def winners(self) -> dict[ExecutionId, Claim]:
        """The holder of each of this robot's open tasks."""
        return self.market.holders()

    def converged(self) -> bool:
        return self.market.converged()

    def waiting_for(self) -> frozenset[str]:
        return self.market.waiting_for()

    # -- what peers say ---------------------------------------------------------------
    def offer(self, sender: str, version: int, tasks: Iterable[Task[T]]) -> bool:
        """``sender``'s open tasks as of ``version``; True if they replaced older ones.
        Tasks of another origin are refused, those over ``max_tasks`` dropped. Told the
        same version again, this robot owes the origin its claim again (it was lost)."""
        if sender not in self.members - {self.robot}:
            return False  # a stranger (perhaps not yet heard of): nothing kept
        old = self._offers.get(sender)
        if old is not None and version <= old.version:
            if version == old.version:
                self._owe.add(sender)
            return False
        kept: dict[ExecutionId, Task[T]] = {}
        for t in tasks:
            if t.id.origin != sender:
                self._refused += 1
            elif len(kept) >= self.max_tasks:
                self.dropped += 1
            else:
                kept[t.id] = t
        self._offers[sender] = _Offer(version, kept)
        return True

    def price(self, board: Board) -> bool:
        """An origin's board; True if newer than the last. One older than our claim says
        nothing of it: the claim may be lost, so it is said again."""
        origin = board.origin
        if origin not in self.members:
            return False
        if origin != self.robot:
            old = self._boards.get(origin)
            if old is not None and board.seq <= old.seq:
                return False
            if len(board.prices) > self.max_tasks:
                self.dropped += len(board.prices) - self.max_tasks
        self._boards[origin] = board
        self._prices[origin] = {t: (p, h) for t, p, h in board.prices[: self.max_tasks]}
        mine = self.claim
        if board.heard < mine.stamp:
            self._owe.add(origin)
        elif mine.task is not None and mine.task.origin == origin:
            price, holder = self._prices[origin].get(mine.task, (math.inf, None))
            if holder != self.robot and price < mine.bid:
                self._barred.add(mine.task)  # refused, not outbid: not ours to take
        return True

    def hear(self, sender: str, claim: Claim, version: int) -> bool:
        """A peer's claim to this robot as an origin, made having merged ``version`` of
        its tasks; True if news. A claim in someone else's name, or with an impossible
        cost, is refused."""
        if sender not in self.members - {self.robot}:
            return False  # a stranger (perhaps not yet heard of): nothing kept
        if claim.robot != sender:
            self._refused += 1
            return False
        if claim.task is not None and not (math.isfinite(claim.cost) and claim.cost >= 0):
            self._refused += 1
            return False
        return self.market.hear(claim, version)

    # -- deciding ---------------------------------------------------------------------
    def _versions(self) -> dict[str, int]:
        out = {o: offer.version for o, offer in self._offers.items()}
        out[self.robot] = self.market.version
        return out

    def tasks(self) -> dict[ExecutionId, Task[T]]:
        """Every open task known, of live origins not under suspicion (one a newer board
        no longer lists is closed)."""
        out = dict(self.market.tasks)
        for origin, offer in self._offers.items():
            if origin in self.suspected:
                continue
            board = self._boards.get(origin)
            if board is not None and board.version >= offer.version:
                listed = self._prices[origin]
                out.update((i, t) for i, t in offer.tasks.items() if i in listed)
            else:
                out.update(offer.tasks)
        return out

    def _price(self, task: ExecutionId) -> tuple[float, str | None]:
        """A task's price and holder as we know them; from a board of an older task set,
        nothing (its prices may have been reset: a bid too low is refused, with news)."""
        origin = task.origin
        if origin == self.robot:
            return self.market.top.get(task, (0.0, None))
        board, offer = self._boards.get(origin), self._offers.get(origin)
        if board is None or (offer is not None and board.version < offer.version):
            return (0.0, None)
        return self._prices[origin].get(task, (0.0, None))

    def _lost(self, task: ExecutionId, tasks: Mapping[ExecutionId, Task[T]]) -> bool:
        """Whether our claim on ``task`` was outbid or refused (not merely unanswered)."""
        if task not in tasks:
            return True
        origin = task.origin
        if origin == self.robot:
            report = self.market.reports.get(self.robot)
            heard = report.claim.stamp if report is not None else 0
        else:
            board = self._boards.get(origin)
            heard = board.heard if board is not None else 0
        return heard >= self.claim.stamp and self._price(task)[1] != self.robot

    def _ceiling(self, origin: str, most: float) -> float:
        """The outside option for ``origin``'s tasks: its board's, or at least ours."""
        known = self.market.ceiling if origin == self.robot else 0.0
        board = self._boards.get(origin)
        if board is not None and origin != self.robot:
            known = board.ceiling
        return max(known, most * (1 + CEILING_MARGIN) + 1e-3)

    def select(self, costs: Mapping[ExecutionId, float]) -> bool:
        """Bid again if this robot must: outbid or refused, its costs, a task set or a
        ceiling changed (``costs``: its own, for the tasks it can take now). True if the
        claim changed, so its origins must hear it."""
        tasks = self.tasks()
        mine = self.claim
        open_costs = {
            t: c
            for t, c in costs.items()
            if t in tasks and self.robot in tasks[t].candidates and math.isfinite(c)
        }
        most = max(open_costs.values(), default=0.0)
        ceilings = {o: self._ceiling(o, most) for o in {t.origin for t in open_costs}}
        basis = (self._versions(), open_costs, ceilings)
        same = self._basis == basis
        if self._basis is not None and self._basis[0] != basis[0]:
            self._barred.clear()
        if same and mine.stamp > 0 and (mine.task is None or not self._lost(mine.task, tasks)):
            return False
        self._basis = basis
        best: tuple[float, str, ExecutionId, float] | None = None
        second = math.inf
        for want, cost in open_costs.items():
            if want in self._barred:
                continue
            net = cost + self._price(want)[0]
            if net >= ceilings[want.origin]:
                continue  # dearer than claiming nothing
            key = (net, str(want), want, cost)
            if best is None or key[:2] < best[:2]:
                if best is not None:
                    second = min(second, best[0])
                best = key
            else:
                second = min(second, net)
        if best is None:
            return self._claim(None, math.inf, 0.0, most)
        net, _, task, cost = best
        price, holder = self._price(task)
        if task == mine.task and (holder == self.robot or not self._lost(task, tasks)):
            return False  # still ours, or our bid on it is on its way
        ceiling = ceilings[task.origin]
        eps = max(DELTA * min(open_costs.values()), FLOOR * ceiling)
        return self._claim(task, cost, price + (min(second, ceiling) - net) + eps, most)

    def _claim(self, task: ExecutionId | None, cost: float, bid: float, most: float) -> bool:
        mine = self.claim
        if mine.stamp > 0 and task is None and mine.task is None and mine.most == most:
            return False
        self.claim = Claim(self.robot, mine.stamp + 1, task, cost, bid, most)
        return True

    def reports(self) -> list[Report]:
        """Our claim for each origin that has not heard it (in the task set it is at);
        this robot's own market hears it at once."""
        out: list[Report] = []
        for origin, version in self._versions().items():
            offer = self._offers.get(origin)
            tasks = self.market.tasks if origin == self.robot else offer.tasks if offer else {}
            if not any(self.robot in t.candidates for t in tasks.values()):
                continue  # nothing of its for us: it does not wait for our word
            now = (self.claim.stamp, version)
            if self._told.get(origin) == now and origin not in self._owe:
                continue
            self._told[origin] = now
            self._owe.discard(origin)
            if origin == self.robot:
                self.market.hear(self.claim, version)
            else:
                out.append(Report(origin, self.claim, version))
        return out

    def boards(self) -> list[tuple[str, Board]]:
        """The boards this robot owes (as an origin), by recipient; its own at once."""
        out = []
        for robot in sorted(self.market.owed):
            board = self.market.board(robot)
            if robot == self.robot:
                self.price(board)
            else:
                out.append((robot, board))
        return out

    def step(
        self, costs: Mapping[ExecutionId, float]
    ) -> tuple[list[Report], list[tuple[str, Board]]]:
        """Select, then what to send: claims to origins and boards to robots. What this
        robot says to itself is heard at once, and it selects again until quiet."""
        reports: list[Report] = []
        boards: list[tuple[str, Board]] = []
        for _ in range(8):
            self.select(costs)
            got, owed = self.reports(), self.boards()
            reports += got
            boards += owed
            if not self.market.owed and not self._lost_own(costs):
                break
        return reports, boards

    def retry(self) -> tuple[list[str], list[tuple[str, Board]]]:
        """For the candidates that have not settled (a message may have been lost), suspects
        too (one that is alive after all is heard): those to tell the task set again (they
        have not reported on it), and the boards for those that must bid again."""
        market, offer, boards = self.market, [], []
        for robot in sorted(market.unsettled() - {self.robot}):
            report = market.reports.get(robot)
            if report is None or report.version != market.version:
                offer.append(robot)
            else:
                boards.append((robot, market.board(robot)))
        return offer, boards

    def _lost_own(self, costs: Mapping[ExecutionId, float]) -> bool:
        task = self.claim.task
        return task is not None and task.origin == self.robot and self._lost(task, self.tasks())
