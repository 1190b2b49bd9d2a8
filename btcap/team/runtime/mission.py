"""Mission control: the actor shell around the sans-IO allocation core.

On the origin side (the robot whose tree holds the capability node) it turns a request
into an auction and the winner into an execution handle; on the executor side it bids,
accepts or declines awards, and runs accepted implementations in the robot's
:class:`~btcap.team.capabilities.slot.RemoteCapabilitySlot` (or hands a run it won for
itself straight to the capability node). What to do is decided by :mod:`btcap.team.core`
(leases, body, bidding) on explicit time; this shell feeds it messages, each with the
sender its transport authenticated, and performs its effects."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from btcap.actors import Actor, Supervision, handler
from btcap.bt.running import nudge, nudge_holder
from btcap.bt.state import State
from btcap.team.allocation.auction import SingleItemAuction
from btcap.team.allocation.strategy import RobotContext, Strategy
from btcap.team.capabilities.capability import ASSIGNER_PATH, Capability
from btcap.team.capabilities.execution import AssignmentRequest
from btcap.team.capabilities.implementation import ImplementationRun
from btcap.team.capabilities.runs import RunFactory
from btcap.team.capabilities.slot import RemoteCapabilitySlot
from btcap.team.core.body import Body
from btcap.team.core.effects import Drop, Effect, Lost, Pause, Refused, Send, Start
from btcap.team.core.hosting import Hosted
from btcap.team.core.origin import merge_keepalives
from btcap.team.ids import ExecutionId
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import (
    Award,
    AwardReply,
    CallForBids,
    CancelExecution,
    CostChanged,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    PauseExecution,
    RunState,
)
from btcap.team.runtime.executor import ExecutorSide
from btcap.team.runtime.moving import Reevaluation
from btcap.team.runtime.origin_side import Handle, OriginSide
from btcap.team.runtime.stats import MissionStats
from btcap.team.settings import MissionConfig
from btcap.transports import Address
from btcap.transports.log import get_logger, worth_logging

__all__ = ["MissionConfig", "MissionControl", "MissionStats"]

#: A hosted run's root state as its origin is told it (same values: the wire is unchanged).
#: A root that skipped itself did nothing, and succeeded as far as its origin can tell.
_RUN_STATE: dict[State, RunState] = {
    s: RunState.SUCCEEDED if s is State.SKIPPED else RunState(s.value) for s in State
}

log = get_logger(__name__)


class MissionControl(Actor):
    """One per robot; see the module docstring."""

    PATH = ASSIGNER_PATH
    #: A peer's bad message must never stop a robot's mission control.
    supervision = Supervision.RESUME

    def __init__(
        self,
        robot: str,
        repository: CapabilityRepository,
        team: Membership,
        strategy: Strategy,
        *,
        config: MissionConfig | None = None,
    ) -> None:
        super().__init__()
        self.robot = robot
        self.repository = repository
        self.team = team
        self.config = config or MissionConfig()
        self.stats = MissionStats()
        self.body = Body(queue_after_current=self.config.queue_after_current, on_free=self.freed)
        #: Grows whenever waiting work may now find a robot (one came free, joined or
        #: changed): capability nodes waiting for one auction again at once.
        self.changes = 0
        self.executor = ExecutorSide(
            robot, repository, self.body, self.stats, self.now, config=self.config
        )
        self.executor.costs.margin = self.config.move_margin
        self.host = self.executor.host
        #: This robot's part of the allocation strategy (spawned beside mission control).
        self.allocator = strategy.allocator(RobotContext(robot, self.config, team, self.executor))
        self.origin_side = OriginSide(
            robot,
            self,
            config=self.config,
            stats=self.stats,
            allocator=self.allocator,
            repository=repository,
            team=team,
            executor=self.executor,
        )
        self.origin = self.origin_side.leases
        #: Every execution a capability node of this robot holds, local or remote.
        self.active: dict[ExecutionId, Handle] = self.origin_side.active
        self._reevaluation = Reevaluation(self.origin_side)
        self._unsubscribe: list[Callable[[], None]] = []
        self._lost_watchers: list[Callable[[Lost], None]] = []

    def watch_lost(self, watcher: Callable[[Lost], None]) -> Callable[[], None]:
        """Tell ``watcher`` why each execution of this robot's nodes was lost (a monitor
        shows it as the reason of the re-auction that follows); returns an unsubscribe."""
        self._lost_watchers.append(watcher)
        w = self._lost_watchers
        return lambda: w.remove(watcher) if watcher in w else None

    def now(self) -> float:
        """The time of the robot's clock (the virtual one in a fast simulation)."""
        return self.system.clock.now()

    @property
    def slot(self) -> RemoteCapabilitySlot | None:
        return self.executor.slot

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self.executor.runs = RunFactory(self.system, self.stats)
        self.executor.runs.prepare(
            i for impls in self.repository.implementations.values() for i in impls
        )
        self._unsubscribe.append(self.team.subscribe(self._on_team))
        # A robot that joins (or rejoins after a partition) is news for waiting work only
        # once its capabilities arrive, which may be after the auction its join set off.
        self._unsubscribe.append(self.repository.subscribe(self._capabilities_known))
        self._unsubscribe.extend(self._reevaluation.start(self.system.clock.sleep))
        self.start_task(self._leases(), name=f"leases {self.robot}")

    def on_stop(self) -> None:
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        # The robot is going away: what it runs for others or itself stops with it.
        self.perform(self.host.drop_all("robot stopping"))
        for execution, run in list(self.executor.local_runs.items()):
            self.origin_side.release(execution, run)

    def attach_slot(self, slot: RemoteCapabilitySlot) -> None:
        self.executor.attach_slot(slot)

    def freed(self) -> None:
        """This robot, or one its work ran on, came free: waiting work may find it now."""
        # The team hears it with the next heartbeat (its ``busy`` flag): not a broadcast per
        # finished task, which would cost every member a message each time.
        self.changes += 1

    def _capabilities_known(self, robot: str) -> None:
        self.changes += 1

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event in (TeamEvent.JOINED, TeamEvent.CHANGED, TeamEvent.FREED):
            if not self._reevaluation.budget(robot, self.now()):
                self.stats.news_ignored += 1  # its news comes faster than we may act on it
                return
            self.changes += 1
            if self.config.reevaluate_s is not None and event is not TeamEvent.JOINED:
                self._reevaluation.news()  # (a join is news once its capabilities are known)
        if event in (TeamEvent.LEFT, TeamEvent.FAILED):
            why = f"robot {robot} {event.value}"
            # A goodbye is said only after the robot's runs stopped (its mission control
            # stops before its membership): a robot that left leaves nothing to wait for.
            left = event is TeamEvent.LEFT
            self.perform(self.origin.member_gone(robot, why, self.now(), stopped=left))
            self.perform(self.host.origin_gone(robot, f"origin {why}"))

    async def _leases(self) -> None:
        """Renew every ``keepalive_s``, and stop a hosted run the moment its lease ends
        (the origin counts on it: :mod:`btcap.team.core.fence`)."""
        clock = self.system.clock
        every = self.config.keepalive_s
        renew_at = clock.now() + every
        while True:
            end = self.host.next_end()
            wake = renew_at if end is None else min(renew_at, end)
            await clock.sleep(max(0.0, wake - clock.now()))
            now = clock.now()
            try:
                if now >= renew_at:
                    renew_at = now + every
                    self.check_leases(now)
                else:
                    self.perform(self.host.expire(now))
            except Exception as exc:  # a bug here must not end lease checking for good
                self.stats.errors += 1
                log.error("mission.lease_check_failed", robot=self.robot, exc_info=exc)

    def check_leases(self, now: float) -> None:
        """Expire lapsed leases on both sides, then renew the live ones in one message
        per peer."""
        self.perform(self.origin.expire(now))
        self.perform(self.host.expire(now))
        renew = merge_keepalives(self.robot, self.origin.keepalives(), self.host.keepalives(now))
        self.perform(renew)
        if self.config.reevaluate_s is not None:  # a rising estimate: look again at once
            self.perform(self.executor.cost_news(self.origin_side.inputs_of))

    # -- performing the core's decisions ------------------------------------------------
    def send(self, robot: str, msg: Any) -> None:
        self.system.tell(Address(robot, self.PATH), msg, sender=self.address)

    def perform(self, effects: Iterable[Effect]) -> None:
        """Carry out the core's decisions (while stopping, only the drops)."""
        if self._system is None or not self.system.running:
            # Stopping: the runs are closed, nobody is told and nothing new starts.
            for e in effects:
                if isinstance(e, Drop):
                    self.executor.drop(e)
            return
        for e in effects:
            try:
                self._do(e)
            except Exception as exc:  # one effect failing must not skip the others
                self.stats.errors += 1
                log.error("mission.effect_failed", robot=self.robot, effect=repr(e), exc_info=exc)
                if isinstance(e, Send) and isinstance(e.message, ExecutionStatus):
                    why = f"its status cannot be sent: {exc}"
                    self.perform(self.host.unsendable(e.message.execution, why))

    def _do(self, e: Effect) -> None:
        if isinstance(e, Send):
            self.send(e.to, e.message)
        elif isinstance(e, Lost):
            handle = self.active.pop(e.execution, None)
            if handle is not None:  # its node re-assigns the work at once
                nudge_holder(handle.node)
            self.stats.lost += 1
            where = {"execution": str(e.execution), "executor": e.executor}
            log.warning("mission.execution_lost", robot=self.robot, why=e.why, **where)
            for watcher in list(self._lost_watchers):
                watcher(e)
        elif isinstance(e, Drop):
            self.executor.drop(e)
        elif isinstance(e, Pause):
            self.host.hosted[e.execution].run.pause()
        elif isinstance(e, Start):
            self.perform(self.executor.start(e.execution))
        elif isinstance(e, Refused):
            self.refused(e.sender, e.message, e.why)

    def refused(self, sender: str, msg: Any, why: str) -> None:
        self.stats.refused += 1
        if worth_logging(self.stats.refused):
            what = {"sender": sender, "message": type(msg).__name__, "why": why}
            log.warning("mission.refused", robot=self.robot, count=self.stats.refused, **what)

    # -- origin side ------------------------------------------------------------------
    def request_assignment(
        self,
        node: Capability,
        inputs: dict[str, Any],
        *,
        local_only: bool = False,
        exclude: frozenset[str] = frozenset(),
    ) -> AssignmentRequest:
        """Start finding an executor for ``node``; never blocks the tick."""
        return self.origin_side.request_assignment(
            node, inputs, local_only=local_only, exclude=exclude
        )

    @handler
    def on_status(self, msg: ExecutionStatus) -> None:
        self.origin_side.status(self.sender, msg)

    @handler
    def on_cost_changed(self, msg: CostChanged) -> None:
        if (why := self._reevaluation.cost_changed(self.sender, msg)) is not None:
            self.refused(self.sender, msg, why)

    @handler
    def on_keepalive(self, msg: KeepAlive) -> None:
        now = self.now()
        self.origin.keepalive(self.sender, msg.executions, now, msg.stamps)
        before = self._hosted_now(now)
        self.host.keepalive(self.sender, msg, now)
        self._hosted_news(before, now)

    def _hosted_now(self, now: float) -> tuple[Any, ...] | None:
        """What the run in the slot acts on: its inputs, whether paused, whether leased."""
        slot = self.executor.slot
        h = None if slot is None else slot.current
        return None if h is None else (h, h.inputs, h.paused, h.leased(now))

    def _hosted_news(self, before: tuple[Any, ...] | None, now: float) -> None:
        """The run in the slot may act on news (its first renewal, new inputs): at once,
        not at the slot tree's next period."""
        if before is not None and self._hosted_now(now) != before:
            nudge(before[0].run.tree)

    # -- executor side ----------------------------------------------------------------
    @handler
    def on_call_for_bids(self, msg: CallForBids) -> None:
        auctioneer = msg.auction.auctioneer
        sender = self.sender
        if sender != auctioneer:  # nobody may have our bids sent to a third robot
            self.refused(sender, msg, f"call for bids of {auctioneer}'s auction")
            return
        answer = self.executor.bid(sender, msg)
        if answer is None:
            self.refused(sender, msg, "over its budget of calls for bids")
            return
        to = Address(auctioneer, SingleItemAuction.PATH)
        self.system.tell(to, answer, sender=self.address)

    @handler
    def on_award(self, msg: Award) -> AwardReply:
        why = self.executor.accept(self.sender, msg)
        if why is None:  # stamped: the origin's echo of it starts the run
            return AwardReply(msg.execution, self.robot, True, stamp=self.now())
        self.stats.declined += 1
        return AwardReply(msg.execution, self.robot, False, why)

    @handler
    def on_inputs(self, msg: ExecutionInputs) -> None:
        now = self.now()
        before = self._hosted_now(now)
        self.perform(self.host.inputs(self.sender, msg, now, self.executor.convert))
        self._hosted_news(before, now)

    @handler
    def on_pause(self, msg: PauseExecution) -> None:
        self.perform(self.host.pause(self.sender, msg))

    @handler
    def on_cancel(self, msg: CancelExecution) -> None:
        if msg.execution.origin == self.robot == self.sender:
            self.origin_side.withdrawn(msg.execution)  # our own auctioneer withdrew it
        self.perform(self.host.cancel(self.sender, msg))

    def hosted_ticked(
        self, hosted: Hosted[ImplementationRun], state: State, outputs: dict[str, Any]
    ) -> None:
        """Called by the slot after each tick of a hosted run."""
        if state is State.SUCCEEDED:
            self.repository.record_success(hosted.run.implementation.interface.name)
        why = hosted.run.why_error() if state is State.ERROR else ""  # for the origin's user
        self.perform(
            self.host.ticked(hosted.execution, _RUN_STATE[state], outputs, self.now(), why)
        )
