"""Mission control: the actor shell around the sans-IO allocation core.

On the origin side (the robot whose tree holds the capability node) it turns a request
into an auction and the winner into an execution handle; on the executor side it bids,
accepts or declines awards, and runs accepted implementations in the robot's
:class:`~btcap.team.slot.RemoteCapabilitySlot` (or hands a run it won for itself straight
to the capability node). What to do is decided by :mod:`btcap.team.core` (leases, body,
bidding) on explicit time; this shell feeds it messages and performs its effects.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Callable, Iterable
from typing import Any

from btcap.actors import Actor, handler
from btcap.bt.state import DONE, State
from btcap.team.assignment import AssignmentStrategy, AssignmentTask, SingleItemAuction
from btcap.team.capability import ASSIGNER_PATH, Capability
from btcap.team.config import MissionConfig, MissionStats
from btcap.team.core.body import Body
from btcap.team.core.effects import Drop, Effect, Lost, Pause, Send, Start
from btcap.team.core.hosting import Hosted
from btcap.team.core.ids import ExecutionId
from btcap.team.core.origin import OriginLeases, merge_keepalives
from btcap.team.execution import AssignmentRequest
from btcap.team.executor import ExecutorSide
from btcap.team.implementation import ImplementationRun
from btcap.team.membership import Membership, TeamEvent
from btcap.team.messages import (
    Award,
    AwardReply,
    CallForBids,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    PauseExecution,
)
from btcap.team.moving import JoinOffers
from btcap.team.proxies import LocalExecution, RemoteExecution
from btcap.team.repository import CapabilityRepository
from btcap.team.runs import RunFactory
from btcap.team.slot import RemoteCapabilitySlot
from btcap.transports import Address
from btcap.transports.log import get_logger

__all__ = ["MissionConfig", "MissionControl", "MissionStats"]

log = get_logger("btcap.mission")

Handle = LocalExecution | RemoteExecution


class MissionControl(Actor):
    """One per robot; see the module docstring."""

    PATH = ASSIGNER_PATH

    def __init__(
        self,
        robot: str,
        repository: CapabilityRepository,
        team: Membership,
        strategy: AssignmentStrategy,
        *,
        config: MissionConfig | None = None,
    ) -> None:
        super().__init__()
        self.robot = robot
        self.repository = repository
        self.team = team
        self.strategy = strategy
        self.config = config or MissionConfig()
        self.stats = MissionStats()
        self.body = Body(queue_after_current=self.config.queue_after_current)
        self.origin = OriginLeases(robot)
        self.executor = ExecutorSide(robot, repository, self.body, self.stats, self._now)
        self.host = self.executor.host
        #: Every execution a capability node of this robot holds, local or remote.
        self.active: dict[ExecutionId, Handle] = {}
        self._ids = itertools.count(1)
        self._offers = JoinOffers(self)
        self._unsubscribe: list[Callable[[], None]] = []

    def _now(self) -> float:
        return self.system.clock.now()

    @property
    def slot(self) -> RemoteCapabilitySlot | None:
        return self.executor.slot

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self.executor.runs = RunFactory(self.system)
        self._unsubscribe.append(self.team.subscribe(self._on_team))
        if self.config.rebid_on_join is not None:
            self._unsubscribe.append(self.repository.subscribe(self._offers.member_joined))
        self.start_task(self._leases(), name=f"leases {self.robot}")

    def on_stop(self) -> None:
        for unsubscribe in self._unsubscribe:
            unsubscribe()
        # The robot is going away: what it runs for others or itself stops with it.
        self._perform(self.host.drop_all("robot stopping"))
        for execution, run in list(self.executor.local_runs.items()):
            self.release(execution, run)

    def attach_slot(self, slot: RemoteCapabilitySlot) -> None:
        self.executor.attach_slot(slot)

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event in (TeamEvent.LEFT, TeamEvent.FAILED):
            why = f"robot {robot} {event.value}"
            self._perform(self.origin.member_gone(robot, why))
            self._perform(self.host.origin_gone(robot, f"origin {why}"))

    async def _leases(self) -> None:
        clock = self.system.clock
        while True:
            await clock.sleep(self.config.keepalive_s)
            try:
                self.check_leases(clock.now())
            except Exception as exc:  # a bug here must not end lease checking for good
                self.stats.errors += 1
                log.error("mission.lease_check_failed", robot=self.robot, exc_info=exc)

    def check_leases(self, now: float) -> None:
        """Expire lapsed leases on both sides, then renew the live ones in one message
        per peer."""
        self._perform(self.origin.expire(now))
        self._perform(self.host.expire(now))
        self._perform(
            merge_keepalives(self.robot, self.origin.keepalives(), self.host.keepalives())
        )

    # -- performing the core's decisions ------------------------------------------------
    def send(self, robot: str, msg: Any) -> None:
        self.system.tell(Address(robot, self.PATH), msg, sender=self.address)

    def _perform(self, effects: Iterable[Effect]) -> None:
        for e in effects:
            if isinstance(e, Send):
                self.send(e.to, e.message)
            elif isinstance(e, Lost):
                self.active.pop(e.execution, None)
                self.stats.lost += 1
                where = {"execution": str(e.execution), "executor": e.executor}
                log.warning("mission.execution_lost", robot=self.robot, why=e.why, **where)
            elif isinstance(e, Drop):
                self.executor.drop(e)
            elif isinstance(e, Pause):
                self.host.hosted[e.execution].run.pause()
            elif isinstance(e, Start):
                self._perform(self.executor.start(e.execution))
            else:
                self.stats.refused += 1
                what = {"sender": e.sender, "message": type(e.message).__name__, "why": e.why}
                log.warning("mission.refused", robot=self.robot, **what)

    def release(self, execution: ExecutionId, run: ImplementationRun) -> None:
        """A run of this robot's own capability nodes ended or was dropped."""
        self.executor.local_runs.pop(execution, None)
        self.executor.close(run)
        effects = self.host.release(execution)
        if self._system is not None and self.system.running:
            self._perform(effects)

    def record_success(self, capability: str) -> None:
        self.repository.record_success(capability)

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
        req = AssignmentRequest()
        self.stats.requests += 1
        iface = type(node).INTERFACE
        providers = self.repository.providers(iface.identity)
        candidates = {self.robot} & providers if local_only else providers & self.team.alive()
        candidates -= exclude
        if not candidates:
            req.done = True
            self.stats.unassigned += 1
            return req
        execution = self.new_execution(node)
        task = AssignmentTask(
            execution,
            iface.name,
            iface.identity,
            inputs,
            frozenset(candidates),
            self.config.lease_s,
        )
        req.task = self.start_task(self._assign(req, task, node), name=f"assign {execution}")
        return req

    def new_execution(self, node: Capability) -> ExecutionId:
        return ExecutionId(self.robot, node.path, next(self._ids))

    def remote(
        self, execution: ExecutionId, robot: str, node: Capability, cost: float
    ) -> RemoteExecution:
        """The handle of an execution ``robot`` accepted; its lease starts now."""
        tracked = self.origin.track(execution, robot, self.config.lease_s, self._now())
        return RemoteExecution(self, tracked, node, cost)

    def let_go(self, ex: Handle, reason: str) -> None:
        """The node let ``ex`` go; a replacement it never adopted goes with it."""
        self.origin.forget(ex.id)
        self.active.pop(ex.id, None)
        if ex.replacement is not None:
            ex.replacement.cancel(reason)
            ex.replacement = None

    async def _assign(self, req: AssignmentRequest, task: AssignmentTask, node: Capability) -> None:
        try:
            won = await self.strategy.assign(task)
        except asyncio.CancelledError:
            run = self.executor.local_runs.get(task.execution)
            if run is not None:  # this robot took the award as the request was cancelled
                self.release(task.execution, run)
            raise
        finally:
            req.done = True
        if won is None:
            self.stats.unassigned += 1
            return
        self.stats.assigned += 1
        if won.robot == self.robot:
            run = self.executor.local_runs.pop(task.execution)
            ex: Handle = LocalExecution(self, task.execution, run, node, won.cost)
        else:
            ex = self.remote(task.execution, won.robot, node, won.cost)
        self.active[ex.id] = ex
        req.execution = ex
        if req.cancelled:
            ex.cancel("request cancelled")
            req.execution = None

    @handler
    def on_status(self, msg: ExecutionStatus) -> None:
        # The sender is who the message says until the transport authenticates peers.
        self._perform(self.origin.status(msg.robot, msg, self._now()))
        if msg.state in DONE and msg.execution not in self.origin.tracked:
            self.active.pop(msg.execution, None)

    @handler
    def on_keepalive(self, msg: KeepAlive) -> None:
        now = self._now()
        self.origin.keepalive(msg.robot, msg.executions, now)
        self.host.keepalive(msg.robot, msg, now)

    # -- executor side ----------------------------------------------------------------
    @handler
    def on_call_for_bids(self, msg: CallForBids) -> None:
        to = Address(msg.auction.auctioneer, SingleItemAuction.PATH)
        self.system.tell(to, self.executor.evaluate(msg), sender=self.address)

    @handler
    def on_award(self, msg: Award) -> AwardReply:
        why = self.executor.accept(msg.auction.auctioneer, msg)
        if why is None:
            return AwardReply(msg.execution, self.robot, True)
        self.stats.declined += 1
        return AwardReply(msg.execution, self.robot, False, why)

    @handler
    def on_inputs(self, msg: ExecutionInputs) -> None:
        now = self._now()
        self._perform(self.host.inputs(msg.execution.origin, msg, now, self.executor.convert))

    @handler
    def on_pause(self, msg: PauseExecution) -> None:
        self._perform(self.host.pause(msg.execution.origin, msg))

    @handler
    def on_cancel(self, msg: CancelExecution) -> None:
        self._perform(self.host.cancel(msg.execution.origin, msg))

    def hosted_ticked(
        self, hosted: Hosted[ImplementationRun], state: State, outputs: dict[str, Any]
    ) -> None:
        """Called by the slot after each tick of a hosted run."""
        if state is State.SUCCEEDED:
            self.repository.record_success(hosted.run.implementation.interface.name)
        self._perform(self.host.ticked(hosted.execution, state, outputs))
