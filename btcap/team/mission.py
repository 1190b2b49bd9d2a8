"""Mission control: serves capability nodes, runs executions, holds their leases.

On the origin side (the robot whose tree holds the capability node) it turns a request
into an auction and the winner into an :class:`~btcap.team.capability.Execution`. On the
executor side it bids, accepts or declines awards, and runs accepted implementations in
the robot's :class:`~btcap.team.slot.RemoteCapabilitySlot` (or, when the origin wins its own
auction, hands the run straight to the capability node). Every robot has one body, so it
runs at most one execution at a time, local or remote; with ``queue_after_current`` it
may hold one more, accepted and waiting for the body.
"""

from __future__ import annotations

import asyncio
import itertools
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import structlog

from btcap.actors import Actor, handler
from btcap.bt.state import DONE, State, TreeError
from btcap.team.assignment import AssignmentStrategy, AssignmentTask
from btcap.team.capability import (
    Capability,
    Implementation,
    ImplementationRun,
    Precondition,
    Scope,
)
from btcap.team.membership import Membership, TeamEvent
from btcap.team.messages import (
    Award,
    AwardReply,
    Bid,
    CallForBids,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    NoBid,
    PauseExecution,
)
from btcap.team.repository import CapabilityRepository
from btcap.transports import Address

if TYPE_CHECKING:
    from btcap.team.slot import RemoteCapabilitySlot

__all__ = [
    "AssignmentRequest",
    "LocalExecution",
    "MissionConfig",
    "MissionControl",
    "MissionStats",
    "RemoteExecution",
]

log = structlog.get_logger("btcap.team.mission")

_LOST = State.SHUTDOWN  # an executor answers an unknown execution with this state


@dataclass(slots=True)
class MissionConfig:
    """Protocol timing in clock seconds."""

    lease_s: float = 1.0
    keepalive_s: float = 0.2
    auction_window_s: float = 1.0
    award_timeout_s: float = 0.5
    #: Move running work to a robot that joins and bids at least this fraction below the
    #: bid the current executor won with (0.25: a quarter cheaper). None, the default:
    #: healthy work is never moved by a join.
    rebid_on_join: float | None = None
    #: A busy robot also bids for one more execution, to start when its current work
    #: ends, at its current bid plus the new one. Off: a busy robot declines to bid.
    queue_after_current: bool = False


@dataclass(slots=True)
class MissionStats:
    requests: int = 0
    assigned: int = 0
    unassigned: int = 0
    lost: int = 0
    hosted: int = 0
    declined: int = 0
    moved: int = 0


class AssignmentRequest:
    """An assignment in progress; the capability node polls ``done`` on its ticks."""

    __slots__ = ("cancelled", "done", "execution", "reason", "task")

    def __init__(self) -> None:
        self.done = False
        self.cancelled = False
        self.execution: LocalExecution | RemoteExecution | None = None
        self.reason = ""
        self.task: asyncio.Task[Any] | None = None

    def cancel(self) -> None:
        self.cancelled = True
        if self.execution is not None:
            self.execution.cancel("request cancelled")
            self.execution = None
        if self.task is not None:
            self.task.cancel()


class _OriginExecution:
    """What the origin knows of every execution it started: who runs it for which node,
    at what bid, and whether it is being moved to another robot."""

    __slots__ = ("_mc", "cost", "id", "node", "replacement", "robot")

    def __init__(
        self, mc: MissionControl, execution: str, robot: str, node: Capability, cost: float
    ) -> None:
        self._mc = mc
        self.id = execution
        self.robot = robot
        self.node = node
        self.cost = cost
        self.replacement: RemoteExecution | None = None

    def hand_over(self) -> RemoteExecution | None:
        """The execution taking over from this one, now the caller's to hold."""
        nxt, self.replacement = self.replacement, None
        return nxt if nxt is not None and not nxt.lost else None

    def _moving(self) -> bool:
        """A replacement waits to be adopted (one lost on the way is forgotten)."""
        nxt = self.replacement
        if nxt is not None and nxt.lost:
            self.replacement = nxt = None
        return nxt is not None


class LocalExecution(_OriginExecution):
    """The origin won its own auction: the capability node ticks the run directly."""

    __slots__ = ("run",)

    def __init__(
        self,
        mc: MissionControl,
        execution: str,
        run: ImplementationRun,
        node: Capability,
        cost: float,
    ) -> None:
        super().__init__(mc, execution, mc.robot, node, cost)
        self.run = run

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        if self.replacement is not None and self._moving():
            return None, {}  # moved: the node adopts the replacement
        if self._mc.occupied != self.id:
            return State.ASSIGNED, {}  # queued behind this robot's current work
        state, outputs = self.run.step(inputs)
        if state is State.SUCCEEDED:
            self._mc.repository.record_success(self.run.implementation.interface.name)
        return state, outputs

    def pause(self) -> None:
        self.run.pause()
        if self.replacement is not None:
            self.replacement.pause()

    def cancel(self, reason: str) -> None:
        self._mc._ended(self, reason)
        self._mc._release(self.id, self.run)


class RemoteExecution(_OriginExecution):
    """The origin's proxy of a run in another robot's slot: inputs out, status back."""

    __slots__ = ("acked", "detail", "last_heard", "lost", "outputs", "seq", "state")

    def __init__(
        self, mc: MissionControl, execution: str, robot: str, node: Capability, cost: float
    ) -> None:
        super().__init__(mc, execution, robot, node, cost)
        self.state = State.ASSIGNED
        self.outputs: dict[str, Any] = {}
        self.seq = 0
        self.acked = 0  # the latest input seq the executor confirmed
        self.lost = False
        self.detail = ""
        self.last_heard = mc.system.clock.now()

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        if self.lost or (
            self.replacement is not None and self.state not in DONE and self._moving()
        ):
            return None, {}  # lost, or moved: the node adopts the replacement
        self.seq += 1
        self._mc._to_mc(self.robot, ExecutionInputs(self.id, self.seq, dict(inputs)))
        return self.state, self.outputs

    def pause(self) -> None:
        if not self.lost:
            self._mc._to_mc(self.robot, PauseExecution(self.id))
        if self.replacement is not None:
            self.replacement.pause()

    def cancel(self, reason: str) -> None:
        self._mc._ended(self, reason)
        if not self.lost:
            self._mc._to_mc(self.robot, CancelExecution(self.id, reason))


@dataclass(slots=True)
class Hosted:
    """A run this robot executes for another robot's capability node."""

    id: str
    origin: str
    run: ImplementationRun
    inputs: dict[str, Any]
    last_heard: float
    state: State = State.ASSIGNED
    outputs: dict[str, Any] | None = None
    paused: bool = False
    seq: int = 0


class MissionControl(Actor):
    """One per robot; see the module docstring."""

    PATH = "mission_control"

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
        self.slot: RemoteCapabilitySlot | None = None
        self.occupied: str | None = None  # the execution using this robot's body
        self.queued: str | None = None  # accepted, to start when the body is free
        self._occupied_cost = 0.0  # what the robot bid for them: queued bids add it
        self._queued_cost = 0.0
        self.origin_executions: dict[str, RemoteExecution] = {}
        # Every execution a capability node of this robot holds, local or remote.
        self.active: dict[str, LocalExecution | RemoteExecution] = {}
        self.hosted: dict[str, Hosted] = {}
        self._local_runs: dict[str, ImplementationRun] = {}
        self._finished: OrderedDict[str, ExecutionStatus] = OrderedDict()
        self._ids = itertools.count(1)
        self._spares: dict[tuple[str, str], ImplementationRun] = {}
        self._unsubscribe: Callable[[], None] | None = None

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self.team.subscribe(self._on_team)
        if self.config.rebid_on_join is not None:
            self._unsubscribe = self.repository.subscribe(self._on_new_member)
        self.start_task(self._leases(), name=f"leases {self.robot}")

    def on_stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
        # The robot is going away: what it runs for others or itself stops with it.
        for h in self._hosted_queued_first():
            self._drop_hosted(h, "robot stopping")
        for execution, run in list(self._local_runs.items()):
            self._release(execution, run)

    def attach_slot(self, slot: RemoteCapabilitySlot) -> None:
        if self.slot is not None and self.slot is not slot:
            raise TreeError(f"robot {self.robot} already has a remote capability slot")
        self.slot = slot

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event not in (TeamEvent.LEFT, TeamEvent.FAILED):
            return
        for ex in list(self.origin_executions.values()):
            if ex.robot == robot:
                self._lose(ex, f"robot {robot} {event.value}")
        for h in self._hosted_queued_first():
            if h.origin == robot:
                self._drop_hosted(h, f"origin {robot} {event.value}")

    async def _leases(self) -> None:
        clock = self.system.clock
        cfg = self.config
        while True:
            await clock.sleep(cfg.keepalive_s)
            now = clock.now()
            by_robot: dict[str, list[str]] = {}
            for ex in list(self.origin_executions.values()):
                if now - ex.last_heard > cfg.lease_s:
                    self._lose(ex, "lease lapsed")
                else:
                    by_robot.setdefault(ex.robot, []).append(ex.id)
            # The executor gives up a little before the origin re-assigns, so the two
            # runs of a partitioned execution never overlap.
            for h in self._hosted_queued_first():
                if now - h.last_heard > 0.8 * cfg.lease_s:
                    self._drop_hosted(h, "origin lease lapsed")
                else:
                    by_robot.setdefault(h.origin, []).append(h.id)
            for robot, ids in by_robot.items():
                self._to_mc(robot, KeepAlive(self.robot, ids))

    def _hosted_queued_first(self) -> list[Hosted]:
        """Dropping several, the queued one goes first: it must not start on the way."""
        return sorted(self.hosted.values(), key=lambda h: h.id != self.queued)

    def _lose(self, ex: RemoteExecution, why: str) -> None:
        if ex.lost:
            return
        ex.lost = True
        self.origin_executions.pop(ex.id, None)
        self.active.pop(ex.id, None)
        self.stats.lost += 1
        log.warning(
            "mission.execution_lost", robot=self.robot, execution=ex.id, executor=ex.robot, why=why
        )

    def _to_mc(self, robot: str, msg: Any) -> None:
        self.system.tell(Address(robot, self.PATH), msg, sender=self.address)

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
            req.reason = f"no robot of the team implements {iface.name}"
            self.stats.unassigned += 1
            return req
        execution = f"{self.robot}:{node.path}:{next(self._ids)}"
        task = AssignmentTask(
            execution,
            iface.name,
            iface.identity,
            inputs,
            frozenset(candidates),
            self.robot,
            self.config.lease_s,
        )
        req.task = self.start_task(self._assign(req, task, node), name=f"assign {execution}")
        return req

    def _remote(self, execution: str, robot: str, node: Capability, cost: float) -> RemoteExecution:
        ex = RemoteExecution(self, execution, robot, node, cost)
        self.origin_executions[execution] = ex
        return ex

    def _ended(self, ex: LocalExecution | RemoteExecution, reason: str) -> None:
        """The node let ``ex`` go; a replacement it never adopted goes with it."""
        self.origin_executions.pop(ex.id, None)
        self.active.pop(ex.id, None)
        if ex.replacement is not None:
            ex.replacement.cancel(reason)
            ex.replacement = None

    # -- moving work to a robot that joins (MissionConfig.rebid_on_join) ---------------
    def _on_new_member(self, robot: str) -> None:
        if self.active and robot != self.robot:
            self.start_task(self._offer_to(robot), name=f"offer work to {robot}")

    def _movable(self, ex: LocalExecution | RemoteExecution) -> bool:
        """Running work its node holds, not being moved, and not paused (no work may start
        for a paused node)."""
        node = ex.node
        return (
            ex.id in self.active
            and ex.replacement is None
            and node.execution is ex
            and node.state is not State.PAUSED
        )

    async def _offer_to(self, robot: str) -> None:
        """Auction running work, costliest first, to ``robot`` alone with the current bid
        less the margin as reserve; the first award it accepts moves that work."""
        margin = self.config.rebid_on_join
        assert margin is not None
        for ex in sorted(self.active.values(), key=lambda e: (-e.cost, e.id)):
            node = ex.node
            iface = type(node).INTERFACE
            if (
                not self._movable(ex)
                or ex.robot == robot
                or node.options["local_only"]
                or robot not in self.repository.providers(iface.identity)
            ):
                continue
            execution = f"{self.robot}:{node.path}:{next(self._ids)}"
            task = AssignmentTask(
                execution,
                iface.name,
                iface.identity,
                dict(node.inputs),
                frozenset({robot}),
                self.robot,
                self.config.lease_s,
                reserve=ex.cost * (1.0 - margin),
                paused=True,  # it starts with the node's next inputs, as the old run stops
            )
            won = await self.strategy.assign(task)
            if won is None:
                continue
            new = self._remote(execution, won.robot, node, won.cost)
            if not self._movable(ex):  # it ended, paused or moved while we asked
                new.cancel("no longer needed")
                continue
            ex.replacement = new
            self.active[new.id] = new
            self.stats.moved += 1
            log.info(
                "mission.moving",
                robot=self.robot,
                execution=ex.id,
                to=robot,
                cost=won.cost,
                was=ex.cost,
            )
            return

    async def _assign(self, req: AssignmentRequest, task: AssignmentTask, node: Capability) -> None:
        try:
            won = await self.strategy.assign(task)
        except asyncio.CancelledError:
            run = self._local_runs.get(task.execution)
            if run is not None:  # this robot took the award as the request was cancelled
                self._release(task.execution, run)
            raise
        finally:
            req.done = True
        if won is None:
            req.reason = "no robot could take it"
            self.stats.unassigned += 1
            return
        self.stats.assigned += 1
        if won.robot == self.robot:
            run = self._local_runs.pop(task.execution)
            ex: LocalExecution | RemoteExecution = LocalExecution(
                self, task.execution, run, node, won.cost
            )
        else:
            ex = self._remote(task.execution, won.robot, node, won.cost)
        self.active[ex.id] = ex
        req.execution = ex
        if req.cancelled:
            req.execution.cancel("request cancelled")
            req.execution = None

    @handler
    def on_status(self, msg: ExecutionStatus) -> None:
        ex = self.origin_executions.get(msg.execution)
        if ex is None or ex.robot != msg.robot:
            return
        ex.last_heard = self.system.clock.now()
        if msg.state is _LOST:
            self._lose(ex, f"executor no longer has it ({msg.detail})")
            return
        ex.state = msg.state
        ex.outputs = msg.outputs
        if msg.seq > ex.acked:
            ex.acked = msg.seq
        ex.detail = msg.detail
        if msg.state in DONE:
            self.origin_executions.pop(ex.id, None)
            self.active.pop(ex.id, None)

    @handler
    def on_keepalive(self, msg: KeepAlive) -> None:
        now = self.system.clock.now()
        for eid in msg.executions:
            ex = self.origin_executions.get(eid)
            if ex is not None and ex.robot == msg.robot:
                ex.last_heard = now
            h = self.hosted.get(eid)
            if h is not None and h.origin == msg.robot:
                h.last_heard = now

    # -- executor side ----------------------------------------------------------------
    def _preconditions_hold(self, pre: tuple[Precondition, ...]) -> str | None:
        for p in pre:
            ok = (
                p.capability in self.repository.succeeded
                if p.scope is Scope.LOCAL
                else self.repository.succeeded_anywhere(p.capability)
            )
            if not ok:
                return f"precondition {p.capability} ({p.scope.value}) not met"
        return None

    def evaluate(self, cfb: CallForBids) -> Bid | NoBid:
        """This robot's answer to a call for bids (pure: reserves nothing)."""
        impls = self.repository.local_implementations(cfb.interface, cfb.identity)
        if not impls:
            return NoBid(cfb.auction, self.robot, "no matching implementation")
        wait = 0.0
        if self.occupied is not None:
            if not self.config.queue_after_current or self.queued is not None:
                return NoBid(cfb.auction, self.robot, "busy")
            wait = self._occupied_cost
        if self.slot is None and cfb.auctioneer != self.robot:
            return NoBid(cfb.auction, self.robot, "no remote capability slot")  # award would fail
        try:
            inputs = impls[0].interface.convert_inputs(cfb.inputs, f"call for bids {cfb.auction}")
        except TreeError as exc:
            return NoBid(cfb.auction, self.robot, str(exc))
        best: tuple[float, str] | None = None
        reasons = []
        for impl in impls:
            why = self._preconditions_hold(impl.preconditions)
            if why is not None:
                reasons.append(why)
                continue
            try:
                cost = impl.cost(inputs)
            except Exception as exc:
                log.error(
                    "mission.bid_failed", robot=self.robot, implementation=impl.name, exc_info=exc
                )
                reasons.append(f"{impl.name}: bid failed")
                continue
            if cost is None:
                reasons.append(f"{impl.name}: cannot execute")
            elif best is None or (cost, impl.name) < best:
                best = (cost, impl.name)
        if best is None:
            return NoBid(cfb.auction, self.robot, "; ".join(reasons))
        return Bid(cfb.auction, self.robot, wait + best[0], best[1])

    @handler
    def on_call_for_bids(self, msg: CallForBids) -> None:
        answer = self.evaluate(msg)
        try:
            reply_to = Address.parse(msg.reply_to)
        except ValueError:
            self.system._count_drop("bad_reply_to", self.address, msg)
            return
        self.system.tell(reply_to, answer, sender=self.address)

    @handler
    def on_award(self, msg: Award) -> AwardReply:
        def decline(reason: str) -> AwardReply:
            self.stats.declined += 1
            return AwardReply(msg.execution, self.robot, False, reason)

        queue = self.occupied is not None
        if queue and (not self.config.queue_after_current or self.queued is not None):
            return decline(f"busy with {self.occupied}")
        impl = next(
            (
                i
                for i in self.repository.local_implementations(msg.interface)
                if i.name == msg.implementation
            ),
            None,
        )
        if impl is None:
            return decline(f"no implementation {msg.implementation!r}")
        why = self._preconditions_hold(impl.preconditions)
        if why is not None:
            return decline(why)
        remote = msg.origin != self.robot
        if remote and self.slot is None:
            return decline("no remote capability slot")
        try:
            inputs = impl.interface.convert_inputs(msg.inputs, f"award {msg.execution}")
            cost = self._cost_of(impl, inputs)
            run = self._take_run(impl)
            # Its nodes become actors of this robot, at a path unique to the execution.
            run.tree.name = msg.execution.replace("/", ".")
            run.tree.attach(self.system)
        except Exception as exc:  # a broken implementation declines, never kills the actor
            if not isinstance(exc, TreeError | ValueError):
                log.error(
                    "mission.build_failed", robot=self.robot, implementation=impl.name, exc_info=exc
                )
            return decline(str(exc))
        hosted = Hosted(
            msg.execution, msg.origin, run, inputs, self.system.clock.now(), paused=msg.paused
        )
        refused: str | None = None
        try:
            # Set up now, so an implementation that cannot start is declined, not run
            # (a queued remote run is set up when the slot takes it).
            if not remote:
                run.tree.setup()
            elif not queue:
                assert self.slot is not None
                refused = self.slot.load(hosted)
        except Exception as exc:
            refused = f"setup of {impl.name!r} failed: {exc}"
        if refused is not None:
            self._close(run)
            return decline(refused)
        if remote:
            self.hosted[msg.execution] = hosted
            self.stats.hosted += 1
        else:
            self._local_runs[msg.execution] = run
        if queue:
            self.queued, self._queued_cost = msg.execution, cost
        else:
            self.occupied, self._occupied_cost = msg.execution, cost
        return AwardReply(msg.execution, self.robot, True)

    def _cost_of(self, impl: Implementation, inputs: Mapping[str, Any]) -> float:
        try:
            return impl.cost(inputs) or 0.0
        except Exception:  # it bid before: a failing estimate only loses queue precision
            return 0.0

    def _start_queued(self) -> None:
        """The body is free: the queued execution takes it."""
        eid, self.queued = self.queued, None
        self.occupied, self._occupied_cost = eid, self._queued_cost
        h = self.hosted.get(eid) if eid is not None else None
        if h is None:
            return  # a local run: its capability node starts ticking it
        assert self.slot is not None
        try:
            refused = self.slot.load(h)
        except Exception as exc:
            refused = f"setup of {h.run.implementation.name!r} failed: {exc}"
        if refused is not None:
            self._to_mc(h.origin, ExecutionStatus(h.id, self.robot, _LOST, {}, h.seq, refused))
            self._drop_hosted(h, refused)

    def _take_run(self, impl: Implementation) -> ImplementationRun:
        """A fresh instance, built ahead of the award when possible (building costs more
        than the rest of an award), and another built right after for next time."""
        key = (impl.interface.name, impl.name)
        run = self._spares.pop(key, None)
        if run is None:
            run = impl.instantiate(self.system.clock)
        asyncio.get_running_loop().call_soon(self._refill, impl)
        return run

    def _refill(self, impl: Implementation) -> None:
        key = (impl.interface.name, impl.name)
        if key in self._spares or self._system is None or not self.system.running:
            return
        try:
            self._spares[key] = impl.instantiate(self.system.clock)
        except Exception as exc:  # the award path will report it with context
            log.debug("mission.prebuild_failed", implementation=impl.name, error=str(exc))

    @handler
    def on_inputs(self, msg: ExecutionInputs) -> None:
        h = self.hosted.get(msg.execution)
        if h is None:
            final = self._finished.get(msg.execution)
            origin = msg.execution.split(":", 1)[0]
            self._to_mc(
                origin,
                final
                or ExecutionStatus(
                    msg.execution, self.robot, _LOST, {}, msg.seq, "unknown execution"
                ),
            )
            return
        try:
            inputs = h.run.implementation.interface.convert_inputs(msg.inputs, f"execution {h.id}")
        except TreeError as exc:
            # Malformed: changes nothing (a bad seq must not make later inputs look stale).
            log.warning("mission.bad_inputs", robot=self.robot, execution=h.id, error=str(exc))
            return
        h.last_heard = self.system.clock.now()
        h.paused = False
        if msg.seq > h.seq:
            h.seq = msg.seq
            h.inputs = inputs
        # Answer at once, so the origin sees fresh state without waiting for our tick.
        self._report(h)

    @handler
    def on_pause(self, msg: PauseExecution) -> None:
        h = self.hosted.get(msg.execution)
        if h is not None:
            h.paused = True
            if h.id != self.queued:  # a queued run has not started: nothing to pause
                h.run.pause()
                h.state = State.PAUSED

    @handler
    def on_cancel(self, msg: CancelExecution) -> None:
        h = self.hosted.get(msg.execution)
        if h is not None:
            self._drop_hosted(h, msg.reason or "cancelled")

    def _report(self, h: Hosted) -> None:
        self._to_mc(h.origin, ExecutionStatus(h.id, self.robot, h.state, h.outputs or {}, h.seq))

    def hosted_ticked(self, h: Hosted, state: State, outputs: dict[str, Any]) -> None:
        """Called by the slot after each tick of a hosted run."""
        h.state, h.outputs = state, outputs
        self._report(h)
        if state in DONE:
            if state is State.SUCCEEDED:
                self.repository.record_success(h.run.implementation.interface.name)
            self._finished[h.id] = ExecutionStatus(h.id, self.robot, state, outputs, h.seq)
            while len(self._finished) > 256:
                self._finished.popitem(last=False)
            self._drop_hosted(h, "finished")

    def _drop_hosted(self, h: Hosted, why: str) -> None:
        if self.hosted.pop(h.id, None) is None:
            return
        if self.slot is not None:
            self.slot.unload(h)
        log.info("mission.hosted_done", robot=self.robot, execution=h.id, why=why)
        self._release(h.id, h.run)

    def _release(self, execution: str, run: ImplementationRun) -> None:
        self._local_runs.pop(execution, None)
        if self.queued == execution:
            self.queued = None
        self._close(run)
        if self.occupied == execution:
            self.occupied = None
            if self.queued is not None and self._system is not None and self.system.running:
                self._start_queued()

    def _close(self, run: ImplementationRun) -> None:
        # Shut the nodes down at once, so nothing of the run works on (also when the
        # system is stopping and no task can run); a system task then waits for its
        # background work and removes its actors. Not this actor's task: stopping mission
        # control must not cancel it before it ran.
        run.tree.root.shutdown()
        system = self._system
        if system is not None and system.running:
            system.start_task(run.close(), name=f"close {run.tree.name}")
