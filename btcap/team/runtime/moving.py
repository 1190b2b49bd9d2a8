"""Re-evaluating running work (the paper's re-auctions during execution, with hysteresis).

Every ``MissionConfig.reevaluate_s`` and whenever the team changes (a robot joins, comes
free or changes), each running execution of this robot's capability nodes is auctioned
again: the robot running it bids what finishing there would cost now, and another robot
wins only with a bid at least ``move_margin`` below that. The winner's run starts paused
and becomes the work's *replacement*, which the capability node adopts on its next tick;
the old run is cancelled only then, so there is no gap and the task never runs twice.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any, Protocol

from btcap.bt.state import State
from btcap.team.allocation.strategy import Allocator
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.proxies import LocalExecution, RemoteExecution
from btcap.team.core.bounds import Budgets
from btcap.team.core.task import Assigned, AssignmentTask
from btcap.team.ids import ExecutionId
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import CostChanged
from btcap.team.runtime.stats import MissionStats
from btcap.team.settings import MissionConfig
from btcap.transports.log import get_logger

__all__ = ["Reevaluation"]

log = get_logger("btcap.mission")

#: A teammate's news sets off work at most this often per auction window, after a burst.
NEWS_PER_WINDOW = 1.0
NEWS_BURST = 4.0

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

    def handle(self, execution: ExecutionId, won: Assigned, node: Capability) -> Handle: ...

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
        return [self.mc.repository.subscribe(self._capabilities)]

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
        new = mc.handle(task.execution, won, node)  # not ticked until the node adopts it
        if not self.movable(ex):  # it ended, paused or moved while we asked
            new.cancel("no longer needed")
            return
        ex.replacement = new
        mc.active[new.id] = new
        mc.stats.moved += 1
        log.info(
            "mission.moving",
            robot=mc.robot,
            execution=str(ex.id),
            frm=ex.robot,
            to=won.robot,
            cost=won.cost,
        )
