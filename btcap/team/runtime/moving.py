"""Re-evaluating running work (the paper's re-auctions during execution, with hysteresis).

Every ``MissionConfig.reevaluate_s`` and whenever the team changes (a robot joins, comes
free or changes), each running execution of this robot's capability nodes is auctioned
again: the robot running it bids what finishing there would cost now, and another robot
wins only with a bid at least ``move_margin`` below that. The winner's run starts paused
and becomes the work's *replacement*, which the capability node adopts on its next tick;
the old run is cancelled only then, so there is no gap and the task never runs twice.

Then two busy robots may *exchange* their running work (:mod:`btcap.team.core.exchange`):
task A goes to B's robot, B bidding as if it handed its own task over and holding A's
new run paused beside it; then task B to A's robot the same way. Only if both were taken
and the pair's total (the holders' fresh bids before, the new bids after) falls by more
than the margin do both become replacements, adopted as above; otherwise both new runs
are cancelled, unstarted, and nothing moved.

Neither undoes itself soon (:mod:`btcap.team.core.handovers`): an exchange is not made
when a robot handing its task over could do the task it gets and then its own for less
than the new robot bids (it would take it back once free), and a task is not handed
back to the robot it left within ``MissionConfig.hold_down_s`` (60 s).
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any, Protocol

from btcap.bt.running import nudge_holder
from btcap.bt.state import State
from btcap.team.allocation.strategy import Allocator, AuctionRecord
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.proxies import LocalExecution, RemoteExecution
from btcap.team.core.bounds import Budgets
from btcap.team.core.exchange import Ledger, Running, pays
from btcap.team.core.handovers import Handovers, comes_back
from btcap.team.core.task import Assigned, AssignmentTask
from btcap.team.ids import ExecutionId
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import CostChanged
from btcap.team.runtime.stats import MissionStats
from btcap.team.settings import MissionConfig
from btcap.transports.log import get_logger

__all__ = ["Reevaluation"]

log = get_logger(__name__)

#: A teammate's news sets off work at most this often per auction window, after a burst.
NEWS_PER_WINDOW = 1.0
NEWS_BURST = 4.0
#: At most this many exchanges (pairs, then chains) are tried per re-evaluation (the
#: dearest running work first): each try is one auction per leg until a leg says no.
EXCHANGE_TRIES = 256
#: The longest cycle of busy robots exchanged at run time (3: pairs and chains of three).
EXCHANGE_CHAIN = 3
#: Chains of three are looked for among this many of the dearest running tasks (the
#: choice looks at every triple: 2 x C(n, 3) cycles).
CHAIN_AMONG = 32

Handle = LocalExecution | RemoteExecution


class Mover(Protocol):
    """What moving work needs from mission control."""

    robot: str
    config: MissionConfig
    stats: MissionStats
    allocator: Allocator
    repository: CapabilityRepository
    active: dict[ExecutionId, Handle]

    def alive(self) -> frozenset[str]: ...

    def now(self) -> float: ...

    def new_execution(self, node: Capability) -> ExecutionId: ...

    def handle(
        self, execution: ExecutionId, won: Assigned, node: Capability, *, paused: bool = False
    ) -> Handle: ...

    def start_task(self, coro: Any, *, name: str | None = None) -> Any: ...


class Reevaluation:
    """One re-evaluation of the running work at a time; news during it asks for another."""

    def __init__(self, mc: Mover) -> None:
        self.mc = mc
        self._running = False
        self._again = False
        window = mc.config.auction_window_s
        #: Each teammate's news (a join, coming free, new capabilities) may set off a
        #: re-evaluation (an auction per running task) or waiting work's auctions:
        #: NEWS_BURST at once, then one per auction window; more waits for the periodic look.
        self.news_budget = Budgets(NEWS_PER_WINDOW / window, NEWS_BURST)
        #: What bidders said about the running work (which exchanges may pay).
        self.ledger = Ledger()
        #: Who each task (capability node) was handed from lately: not back within the
        #: hold-down.
        self.handovers = Handovers(mc.config.hold_down_s)

    def budget(self, robot: str, now: float) -> bool:
        """Whether news from ``robot`` may set off work now (spent if so)."""
        return self.news_budget.allow(robot, now)

    @property
    def margin(self) -> float:
        cfg = self.mc.config
        return cfg.rebid_on_join if cfg.rebid_on_join is not None else cfg.move_margin

    def start(self, sleep: Callable[[float], Awaitable[None]]) -> list[Callable[[], None]]:
        """Look every ``reevaluate_s`` and whenever capabilities arrive (a joining robot's
        come after its join: that is the news); returns what to unsubscribe."""
        cfg = self.mc.config
        if cfg.reevaluate_s is not None:
            self.mc.start_task(self._every(cfg.reevaluate_s, sleep), name="re-evaluation")
        if cfg.reevaluate_s is None and cfg.rebid_on_join is None:
            return []
        stop = [self.mc.repository.subscribe(self._capabilities)]
        if self.mc.allocator.exchanges:
            stop.append(self.mc.allocator.watch(self._heard))
        return stop

    def _capabilities(self, robot: str) -> None:
        if self.budget(robot, self.mc.now()):
            self.news()
        else:
            self.mc.stats.news_ignored += 1

    async def _every(self, period: float, sleep: Callable[[float], Awaitable[None]]) -> None:
        while True:
            await sleep(period)
            self.news()

    def news(self) -> None:
        """The team changed, or it is time: look at the running work again."""
        if not self.mc.active:
            if self.ledger.held or self.ledger.cross:
                self.ledger.keep(())  # nothing runs: nothing said is of use
            return
        if self._running:
            self._again = True
            return
        self._running = True
        self.mc.start_task(self._run(), name=f"re-evaluate {self.mc.robot}")

    def cost_changed(self, sender: str, msg: CostChanged) -> str | None:
        """Its executor's estimate of a running execution rose: look again now. Why the
        message is refused, or None."""
        ex = self.mc.active.get(msg.execution)
        if ex is None:
            return None  # it ended meanwhile
        if ex.robot != sender:
            return f"cost of {msg.execution} from another robot than its executor {ex.robot}"
        ex.cost = msg.cost
        if self.mc.allocator.exchanges:  # kept only where exchanges forget it again
            self.ledger.holder(msg.execution, msg.cost)
        if self.mc.config.reevaluate_s is not None:  # None: this origin never moves work
            self.news()
        return None

    def movable(self, ex: Handle) -> bool:
        """Running work its node holds, not being moved, and not paused (no work may start
        for a paused node)."""
        node = ex.node
        return (
            ex.id in self.mc.active
            and ex.replacement is None
            and node.execution is ex
            and node.state is State.RUNNING
            and not node.options["local_only"]
        )

    async def _run(self) -> None:
        try:
            while True:
                self._again = False
                for ex in sorted(self.mc.active.values(), key=lambda e: (-e.cost, str(e.id))):
                    if self.movable(ex):
                        await self._offer(ex)
                if self.mc.allocator.exchanges:
                    await self._exchanges()
                if not self._again:
                    return
        finally:
            self._running = False

    async def _offer(self, ex: Handle) -> None:
        mc = self.mc
        node = ex.node
        iface = type(node).INTERFACE
        # Others (this robot too) may take it over; its holder bids what finishing would
        # cost it now.
        others = (mc.repository.providers(iface.identity) & mc.alive()) - {ex.robot}
        barred = self.handovers.barred(id(node), mc.now()) & others
        if barred:  # it left those robots lately: not back within the hold-down
            others -= barred
            mc.stats.held_back += 1
        if not others:
            return
        candidates = others | {ex.robot}
        task = AssignmentTask(
            mc.new_execution(node),
            iface.name,
            iface.identity,
            dict(node.inputs),
            frozenset(candidates),
            mc.config.lease_s,
            paused=True,  # it starts with the node's next inputs, as the old run stops
            holder=ex.id,
            holder_robot=ex.robot,
            margin=self.margin,
        )
        won = await mc.allocator.assign(task)
        if not isinstance(won, Assigned):
            return
        # not ticked until the node adopts it
        new = mc.handle(task.execution, won, node, paused=True)
        if not self.movable(ex):  # it ended, paused or moved while we asked
            new.cancel("no longer needed")
            return
        ex.replacement = new
        mc.active[new.id] = new
        nudge_holder(ex.node)  # adopted at the node's next tick: now
        mc.stats.moved += 1
        mc.stats.undone += self.handovers.moved(id(node), ex.robot, won.robot, mc.now())
        log.info(
            "mission.moving",
            robot=mc.robot,
            execution=str(ex.id),
            frm=ex.robot,
            to=won.robot,
            cost=won.cost,
        )

    def _heard(self, record: AuctionRecord) -> None:
        """What bidders said in a re-evaluation or exchange auction, for the ledger."""
        task, outcome = record.task, record.outcome
        if outcome is None or task.holder is None:
            return
        bids = {b.robot: b.cost for b in outcome.ranking}
        held = bids.get(task.holder_robot or "")
        if held is not None:
            self.ledger.holder(task.holder, held)
        if task.handing is not None:
            to = next(iter(task.candidates - {task.holder_robot}), None)
            if to in bids:
                self.ledger.leg(task.handing, task.holder, bids[to])
            elif to in outcome.declined:
                self.ledger.leg(task.handing, task.holder, None)

    async def _exchanges(self) -> None:
        """Exchanges of running work between busy robots, neither this one, each running
        one task of this origin's: pairs (the dearest work first), then chains of three,
        each robot in one exchange; a cycle is auctioned only if what its bidders already
        said leaves it a chance to pay (:class:`~btcap.team.core.exchange.Ledger`)."""
        mc = self.mc
        by_robot: dict[str, list[Handle]] = {}
        for ex in mc.active.values():
            if isinstance(ex, RemoteExecution) and ex.robot != mc.robot and self.movable(ex):
                by_robot.setdefault(ex.robot, []).append(ex)
        solo = sorted(
            (held[0] for held in by_robot.values() if len(held) == 1),
            key=lambda e: (-e.cost, str(e.id)),
        )
        self.ledger.keep(mc.active.keys())
        handles = {ex.id: ex for ex in solo}
        running = [Running(ex.id, ex.robot, ex.cost) for ex in solo]
        chain = EXCHANGE_CHAIN if len(solo) > 2 else 2
        exchanged: set[str] = set()
        tries = 0
        cycles = self.ledger.cycles(running, self.margin, chain=chain, chain_of=CHAIN_AMONG)
        for cycle in cycles:
            if tries >= EXCHANGE_TRIES:
                mc.stats.exchange_tries_left_off += 1
                return
            if any(t.robot in exchanged for t in cycle):
                continue
            if not self._allowed([handles[t.execution] for t in cycle]):
                mc.stats.held_back += 1
                continue
            tries += 1
            if await self._cycle([handles[t.execution] for t in cycle]):
                exchanged |= {t.robot for t in cycle}

    def _allowed(self, cycle: list[Handle]) -> bool:
        """Whether no task of ``cycle`` would go back to a robot it left lately."""
        now, n = self.mc.now(), len(cycle)
        return all(
            self.handovers.allows(id(x.node), cycle[(i + 1) % n].robot, now)
            for i, x in enumerate(cycle)
        )

    def _returns(self, legs: list[Assigned]) -> bool:
        """Whether a robot of the cycle would take its task back once free: it could do
        the task it receives, then its own, for less than the new robot bids."""
        n, m = len(legs), self.margin
        return any(
            comes_back(legs[i - 1].cost, legs[i].held or 0.0, legs[i].cost, m) for i in range(n)
        )

    async def _cycle(self, cycle: list[Handle]) -> bool:
        """Give each task of ``cycle`` to the next one's robot if the total falls by more
        than the margin: leg by leg, each accepted paused and only while the cycle could
        still gain (each leg's bid must stay below what the legs so far saved plus the
        last known costs of the tasks still to go); all adopted, or none."""
        mc = self.mc
        n, m = len(cycle), self.margin
        legs: list[tuple[Handle, Assigned]] = []
        for i, x in enumerate(cycle):
            y = cycle[(i + 1) % n]
            done = [won for _new, won in legs]
            if any(won.held is None for won in done):
                credit = -1e300
            elif i < n - 1:
                rest = sum(self.ledger.held.get(t.id, t.cost) for t in cycle[i + 1 :])
                credit = sum((won.held or 0.0) - won.cost for won in done) + rest
            else:
                credit = sum((won.held or 0.0) * (1.0 - m) - won.cost for won in done)
            leg = await self._leg(x, y, m if i == n - 1 else 0.0, credit)
            if leg is None:
                for new, _won in legs:
                    new.cancel("exchange off")
                return False
            legs.append(leg)
        won_all = [won for _new, won in legs]
        before = sum(won.held or 0.0 for won in won_all)
        after = sum(won.cost for won in won_all)
        held = all(won.held is not None for won in won_all)
        back = held and pays(before, after, m) and self._returns(won_all)
        if back:
            mc.stats.foreseen_back += 1
        if back or not (held and pays(before, after, m)) or not all(map(self.movable, cycle)):
            for new, _won in legs:
                new.cancel("exchange off")
            return False
        now = mc.now()
        for i, (old, (new, _won)) in enumerate(zip(cycle, legs, strict=True)):
            old.replacement = new
            mc.active[new.id] = new
            to = cycle[(i + 1) % n].robot
            mc.stats.undone += self.handovers.moved(id(old.node), old.robot, to, now)
            nudge_holder(old.node)
        mc.stats.moved += n
        mc.stats.exchanged += 1
        log.info(
            "mission.exchanging",
            robot=mc.robot,
            executions=[str(x.id) for x in cycle],
            robots=[x.robot for x in cycle],
            before=before,
            after=after,
        )
        return True

    async def _leg(
        self, x: Handle, y: Handle, margin: float, credit: float
    ) -> tuple[Handle, Assigned] | None:
        """``x``'s task offered to ``y``'s robot, which bids as if it handed ``y`` over
        and holds the new run paused beside it; ``x``'s robot bids as its holder."""
        mc = self.mc
        node = x.node
        iface = type(node).INTERFACE
        if y.robot not in mc.repository.providers(iface.identity) & mc.alive():
            return None
        if not (self.movable(x) and self.movable(y)):
            return None
        task = AssignmentTask(
            mc.new_execution(node),
            iface.name,
            iface.identity,
            dict(node.inputs),
            frozenset({x.robot, y.robot}),
            mc.config.lease_s,
            paused=True,
            holder=x.id,
            holder_robot=x.robot,
            margin=margin,
            handing=y.id,
            credit=credit,
        )
        won = await mc.allocator.assign(task)
        if not isinstance(won, Assigned):
            return None
        new = mc.handle(task.execution, won, node, paused=True)
        if won.robot != y.robot:  # the holder is never awarded its own work: a bad peer
            new.cancel("exchange off")
            return None
        return new, won
