"""The origin's side of mission control: finding executors for this robot's capability
nodes and keeping the handles they tick.

Which executions live is decided by the core's :class:`~btcap.team.core.origin.OriginLeases`;
this part runs the assignment strategy and turns its winner into a handle. What it needs
from its robot's mission control is the small :class:`OriginHost`.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Coroutine, Iterable
from typing import Any, Protocol

from btcap.bt.running import nudge_holder
from btcap.bt.state import TreeError
from btcap.team.allocation.strategy import Allocator
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.execution import AssignmentRequest
from btcap.team.capabilities.implementation import ImplementationRun
from btcap.team.capabilities.proxies import LocalExecution, RemoteExecution
from btcap.team.core.body import Body
from btcap.team.core.effects import Effect
from btcap.team.core.origin import OriginLeases, Tracked
from btcap.team.core.task import Assigned, AssignmentTask
from btcap.team.ids import ExecutionId
from btcap.team.membership.membership import Membership
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import RUN_DONE, ExecutionStatus, KeepAlive
from btcap.team.runtime.executor import ExecutorSide
from btcap.team.runtime.stats import MissionStats
from btcap.team.settings import MissionConfig

__all__ = ["Handle", "OriginHost", "OriginSide"]

Handle = LocalExecution | RemoteExecution


class OriginHost(Protocol):
    """What the origin side needs from its robot's mission control (the actor shell)."""

    def send(self, robot: str, msg: Any) -> None:
        """Tell ``robot``'s mission control ``msg``."""
        ...

    def perform(self, effects: Iterable[Effect]) -> None:
        """Carry out the core's decisions."""
        ...

    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]:
        """Run ``coro`` in the background until mission control stops."""
        ...

    def now(self) -> float:
        """The time of the robot's clock."""
        ...

    def freed(self) -> None:
        """A robot this one's work ran on is free again: waiting work may find it now."""
        ...


class OriginSide:
    """Assignments and execution handles of one robot's capability nodes."""

    def __init__(
        self,
        robot: str,
        host: OriginHost,
        *,
        config: MissionConfig,
        stats: MissionStats,
        allocator: Allocator,
        repository: CapabilityRepository,
        team: Membership,
        executor: ExecutorSide,
    ) -> None:
        self.robot = robot
        self.host = host
        self.config = config
        self.stats = stats
        self.allocator = allocator
        self.repository = repository
        self.team = team
        self.executor = executor
        self.body: Body = executor.body
        #: Bound once: every remote handle sends its node's inputs through it each tick.
        self.send = host.send
        self.leases = OriginLeases(robot)
        #: Every execution a capability node of this robot holds, local or remote.
        self.active: dict[ExecutionId, Handle] = {}
        self._ids = itertools.count(1)

    def alive(self) -> frozenset[str]:
        return self.team.alive()

    def now(self) -> float:
        return self.host.now()

    def start_task(self, coro: Coroutine[Any, Any, Any], *, name: str | None = None) -> Any:
        return self.host.start_task(coro, name=name)

    def inputs_of(self, execution: ExecutionId) -> dict[str, Any] | None:
        """The latest inputs of the node holding ``execution`` (None once it ended)."""
        ex = self.active.get(execution)
        return None if ex is None else dict(ex.node.inputs)

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
            req.why = {
                "team": f"no live member{' but excluded ones' if exclude else ''} "
                f"implements {iface.name}"
            }
            self.stats.unassigned += 1
            return req
        execution = self.new_execution(node)
        # A run of this task given up on may still act: the next one is held until then.
        fenced = self.leases.fenced(execution.node, self.host.now()) is not None
        task = AssignmentTask(
            execution,
            iface.name,
            iface.identity,
            inputs,
            frozenset(candidates),
            self.config.lease_s,
            paused=fenced,
        )
        req.task = self.start_task(self._assign(req, task, node), name=f"assign {execution}")
        return req

    def new_execution(self, node: Capability) -> ExecutionId:
        # The membership's incarnation: a restarted robot's ids differ from its last life's.
        return ExecutionId(self.robot, node.path, next(self._ids), self.team.incarnation)

    def remote(
        self,
        execution: ExecutionId,
        won: Assigned,
        node: Capability,
        *,
        paused: bool = False,
    ) -> RemoteExecution:
        """The handle of an execution ``won.robot`` accepted; its lease starts now, and
        the echo of its acceptance's stamp goes out at once: the run starts with it."""
        robot, now = won.robot, self.host.now()
        lease_s = self.config.lease_s
        tracked = self.leases.track(execution, robot, lease_s, now, stamp=won.stamp, paused=paused)
        if won.stamp is not None:
            self.send(robot, KeepAlive(self.robot, [execution], [won.stamp]))
        return RemoteExecution(self, tracked, node, won.cost)

    def handle(
        self, execution: ExecutionId, won: Assigned, node: Capability, *, paused: bool = False
    ) -> Handle:
        """The handle of an execution ``won.robot`` accepted (``paused``: awarded to start
        with its first inputs): this robot's own run, ticked by the node, or a proxy of one
        on another robot (its lease starts now)."""
        if won.robot == self.robot:
            run = self.executor.local_runs.pop(execution)
            return LocalExecution(self, execution, run, node, won.cost)
        return self.remote(execution, won, node, paused=paused)

    def fenced(self, execution: ExecutionId) -> bool:
        """Whether a run of ``execution``'s task given up on may still act (so this one
        must not start yet)."""
        return self.leases.fenced(execution.node, self.host.now()) is not None

    def let_go(self, ex: Handle, reason: str) -> None:
        """The node let ``ex`` go; a replacement it never adopted goes with it."""
        self.leases.forget(ex.id, self.host.now())
        self.active.pop(ex.id, None)
        if ex.replacement is not None:
            ex.replacement.cancel(reason)
            ex.replacement = None

    def release(self, execution: ExecutionId, run: ImplementationRun) -> None:
        """A run of this robot's own ended, was dropped or was never adopted."""
        self.executor.local_runs.pop(execution, None)
        self.executor.close(run)
        self.host.perform(self.executor.host.release(execution))

    def record_success(self, capability: str) -> None:
        self.repository.record_success(capability)

    def withdrawn(self, execution: ExecutionId) -> None:
        """Our own auctioneer gave up on an award this robot took for itself."""
        run = self.executor.local_runs.get(execution)
        if run is not None and execution not in self.active:
            self.release(execution, run)

    async def _assign(self, req: AssignmentRequest, task: AssignmentTask, node: Capability) -> None:
        try:
            won = await self.allocator.assign(task)
        except asyncio.CancelledError:
            self.withdrawn(task.execution)  # taken for itself as the request was cancelled
            raise
        finally:
            req.done = True
            if not req.cancelled:  # the node acts on the outcome at once, not a period later
                nudge_holder(node)
        if not isinstance(won, Assigned) or won.robot != self.robot:
            self.withdrawn(task.execution)  # a self-award it gave up on, then took
        if not isinstance(won, Assigned):
            self.leases.abandon(task.execution)
            req.why = dict(won.reasons)
            self.stats.unassigned += 1
            return
        self.stats.assigned += 1
        ex = self.handle(task.execution, won, node, paused=task.paused)
        self.active[ex.id] = ex
        req.execution = ex
        if req.cancelled:
            ex.cancel("request cancelled")
            req.execution = None

    def status(self, sender: str, msg: ExecutionStatus) -> None:
        """A report on a remote execution: its outputs typed by the node's interface. One
        that changed what its node reads (state, outputs, lost) ticks the node's tree soon."""
        t = self.leases.tracked.get(msg.execution)
        before = None if t is None else (t.state, t.outputs, t.lost)
        self.host.perform(self.leases.status(sender, msg, self.host.now(), self._convert))
        if t is not None and (t.state, t.outputs, t.lost) != before:
            handle = self.active.get(msg.execution)
            if handle is not None:
                nudge_holder(handle.node)
        if msg.state in RUN_DONE and msg.execution not in self.leases.tracked:
            handle = self.active.get(msg.execution)
            if isinstance(handle, RemoteExecution) and handle.tracked.state in RUN_DONE:
                self.active.pop(msg.execution)  # its result was taken
                # Its executor is free now: work waiting for a robot competes for it at
                # once, with the task that follows this one (not a heartbeat later).
                self.host.freed()

    def _convert(self, t: Tracked, values: dict[str, Any]) -> dict[str, Any] | str:
        handle = self.active.get(t.execution)
        if handle is None:
            return dict(values)  # a replacement not yet adopted: its node reads them later
        try:
            return type(handle.node).INTERFACE.convert_outputs(values, f"status of {t.execution}")
        except TreeError as exc:
            return str(exc)
