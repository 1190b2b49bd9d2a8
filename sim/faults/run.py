"""One deterministic simulation test run: real agents on a :class:`FaultyNetwork`, on the
virtual clock, driven by a :class:`~btcap.sim.faults.plan.Plan`.

The origin ``op`` holds the mission tree and is ticked here, one tick at a time; the
plan's faults happen at their clock times; after every tick and every fault the
invariants of :mod:`btcap.sim.faults.check` are checked. At ``heal_at`` every fault ends
(partitions healed, frozen robots thawed, crashed ones restarted, robots that left
rejoin, clean links) and the mission must then complete within ``quiet_s``.
"""

from __future__ import annotations

import asyncio
import random
from dataclasses import dataclass, field

from btcap.actors import ManualClock
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.sim.faults.check import Checker
from btcap.sim.faults.network import FaultyNetwork, LinkFaults, NetCounters, Tap
from btcap.sim.faults.plan import ORIGIN, Fault, Plan
from btcap.sim.faults.work import implementations, mission
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.proxies import RemoteExecution
from btcap.team.membership.membership import TeamEvent
from btcap.team.messages import (
    RUN_DONE,
    Award,
    AwardReply,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
)
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.background import Background, start_in_background
from btcap.team.runtime.protocol import protocol_registry
from btcap.team.settings import AgentConfig
from btcap.transports.codec import Envelope

__all__ = ["Outcome", "config_for", "run_plan"]


def config_for(plan: Plan) -> AgentConfig:
    """The protocol's default timing, 2.5 times slower (fewer messages per clock second
    for the same ratios), re-evaluating every 5 s so that running work moves."""
    return AgentConfig(
        tick_hz=4.0,
        heartbeat_s=0.25,
        failure_timeout_s=1.25,
        lease_s=2.5,
        keepalive_s=0.5,
        auction_window_s=2.5,
        award_timeout_s=1.25,
        reevaluate_s=5.0,
        strategy=plan.strategy,
    )


@dataclass
class Outcome:
    """What a run showed: the first violated invariants (empty: all held) and its trace."""

    plan: Plan
    violations: list[str]
    trace: list[str]
    end_s: float
    counters: NetCounters
    done: bool = False
    failures: int = 0  #: members the origin declared failed (false ones included)
    double_ticks: int = 0  #: ticks of a run while another of its task acted (0: none)

    @property
    def ok(self) -> bool:
        return not self.violations


@dataclass
class _Run:
    plan: Plan
    clock: ManualClock
    net: FaultyNetwork
    checker: Checker
    cfg: AgentConfig
    trace: list[str] = field(default_factory=list)
    lives: dict[str, Background] = field(default_factory=dict)
    crashed: set[str] = field(default_factory=set)
    left: set[str] = field(default_factory=set)
    incarnation: int = 0
    failures: int = 0
    origins: tuple[str, ...] = (ORIGIN,)

    def note(self, what: str) -> None:
        self.trace.append(f"{self.clock.now():8.3f}  {what}")

    async def start(self, robot: str) -> None:
        impls = implementations(self.plan, robot, self.checker)
        agent = Agent(
            robot,
            transport=self.net.transport(robot),
            clock=self.clock,
            implementations=impls,
            config=self.cfg,
        )
        # Incarnations from the run, not the wall: the same plan, the same ids.
        self.incarnation += 1
        agent.team.incarnation = self.incarnation
        if robot in self.origins:
            agent.team.subscribe(lambda event, member: self._origin_saw(robot, event, member))
            agent.mission_control.watch_lost(lambda lost: self.checker.gave_up(str(lost.execution)))
        self.lives[robot] = await start_in_background(agent)

    async def stop(self, robot: str) -> None:
        await self.lives.pop(robot).stop()

    def _origin_saw(self, origin: str, event: TeamEvent, robot: str) -> None:
        if event is TeamEvent.FREED:
            return
        self.note(f"{origin} sees {robot} {event.value}")
        if event is TeamEvent.FAILED:
            self.failures += 1
            self.checker.declared_failed(robot, self.clock.now())
            # Runs on it whose result has not come are given up from now on (this
            # listener runs before mission control's, which loses them).
            for handle in self.lives[origin].agent.mission_control.active.values():
                t = handle.tracked if isinstance(handle, RemoteExecution) else None
                if t is not None and t.executor == robot and t.state not in RUN_DONE:
                    self.checker.gave_up(str(handle.id))

    async def apply(self, f: Fault) -> None:
        self.note(f"fault: {f.line().strip()}")
        robot = f.robots[0] if f.robots else ""
        if f.kind == "net":
            self.net.faults = LinkFaults(*f.rates)
        elif f.kind == "partition":
            self.net.partition(f.groups)
        elif f.kind == "oneway":
            self.net.cut_oneway(*f.robots)
        elif f.kind == "heal":
            self.net.heal()
        elif f.kind == "freeze" and robot in self.lives:
            self.net.freeze(robot)
        elif f.kind == "thaw":
            self.net.thaw(robot)
        elif f.kind == "crash" and robot in self.lives:
            self.net.crash(robot)
            await self.stop(robot)
            self.crashed.add(robot)
        elif f.kind in ("restart", "join") and robot not in self.lives:
            self.crashed.discard(robot)
            self.left.discard(robot)
            await self.start(robot)
        elif f.kind == "leave" and robot in self.lives:
            self.net.thaw(robot)
            await self.stop(robot)
            self.left.add(robot)
        elif f.kind == "mirror":
            self.net.tap = _mirror(robot)
            # ... and what it reports on them is lost, so nobody stops its copies.
            self.net.mute = lambda src, env: src == robot and isinstance(env.msg, ExecutionStatus)

    async def heal_all(self) -> None:
        self.note("heal: every fault ends")
        self.net.faults = LinkFaults()
        self.net.heal()
        for robot in self.net.frozen:
            self.net.thaw(robot)
        for robot in sorted((self.crashed | self.left) & set(self.plan.initial)):
            self.crashed.discard(robot)
            self.left.discard(robot)
            await self.start(robot)

    def watch(self, sender: str, env: Envelope) -> None:
        """What a robot says, checked against what it does as it says it."""
        msg = env.msg
        if isinstance(msg, AwardReply) and not msg.accepted and sender in self.lives:
            body = self.lives[sender].agent.mission_control.body
            holds = body.holds(msg.execution)
            self.checker.declined(sender, str(msg.execution), holds, msg.reason, self.clock.now())


def _mirror(to: str) -> Tap:
    def tap(src: str, dest: str, env: object) -> list[str]:
        msg = getattr(env, "msg", None)
        if dest != to and isinstance(msg, Award | ExecutionInputs | KeepAlive):
            return [to]
        return []

    return tap


@dataclass
class _Mission:
    origin: str
    tree: Tree
    nodes: list[Capability]
    state: State = State.IDLE


async def _drive(r: _Run) -> bool:
    plan, clock, checker = r.plan, r.clock, r.checker
    names = len(set(plan.robots) | {ORIGIN})
    for robot in (ORIGIN, *plan.initial):
        await r.start(robot)
    missions = []
    for origin, tasks in zip(r.origins, (plan.tasks, plan.second), strict=False):
        root, nodes = mission(plan, tasks)
        missions.append(_Mission(origin, r.lives[origin].agent.mission(root), nodes))
    all_nodes = [node for m in missions for node in m.nodes]
    pending = sorted(plan.faults, key=lambda f: f.at)
    healed = False
    tick_s = 1.0 / r.cfg.tick_hz
    seen: dict[str, tuple[str, str]] = {}
    adopted: dict[str, str] = {}  # node -> its latest execution
    try:
        while True:
            now = clock.now()
            while pending and pending[0].at <= now:
                await r.apply(pending.pop(0))
            if not healed and now >= plan.heal_at:
                healed = True
                pending.clear()
                await r.heal_all()
            for m in missions:
                if m.state is not State.SUCCEEDED:
                    m.state = m.tree.tick()
            now = clock.now()
            for m in missions:
                for node in m.nodes:
                    _observe(r, m.origin, node, seen, adopted, now)
            agents = [life.agent for life in r.lives.values()]
            checker.bounds(now, agents, names, len(all_nodes))
            if checker.violations:
                return False
            if all(m.state is State.SUCCEEDED for m in missions):
                return True
            if any(m.state is State.FAILED for m in missions):
                checker.violations.append(f"{now:.3f} the mission failed")
                return False
            if now > plan.heal_at + plan.quiet_s:
                left = [n.name for n in all_nodes if n.state is not State.SUCCEEDED]
                checker.violations.append(
                    f"{now:.3f} not live: tasks {', '.join(left)} not done {plan.quiet_s:.0f} s "
                    "after every fault healed"
                )
                return False
            wake = now + tick_s
            if pending:
                wake = min(wake, pending[0].at)
            if not healed:
                wake = min(wake, plan.heal_at)
            await clock.sleep_until(wake)
    finally:
        for m in missions:
            await m.tree.shutdown()


def _observe(
    r: _Run,
    origin: str,
    node: Capability,
    seen: dict[str, tuple[str, str]],
    adopted: dict[str, str],
    now: float,
) -> None:
    """Note where ``node``'s execution runs; a success is credited to its runner."""
    ex = node.execution
    if ex is not None:
        adopted[node.name] = str(ex.id)
    where = (node.state.value, ex.robot if ex is not None else "")
    if seen.get(node.name) == where:
        return
    seen[node.name] = where
    r.note(f"{node.name} {where[0]}" + (f" on {where[1]}" if where[1] else ""))
    if node.state is State.SUCCEEDED:
        out = node.outputs
        execution = adopted.get(node.name, "")
        r.checker.credit(origin, node.name, out["robot"], out["run"], execution, now)


async def _run(plan: Plan) -> Outcome:
    clock = ManualClock()
    net = FaultyNetwork(clock, random.Random(plan.seed * 7919 + 17), protocol_registry())
    cfg = config_for(plan)
    r = _Run(plan, clock, net, Checker(), cfg)
    if plan.second:
        r.origins = (ORIGIN, plan.initial[0])
    net.watch = r.watch
    r.note(f"plan: seed {plan.seed}, {plan.strategy}, robots {', '.join(plan.initial)}")
    done = False
    async with clock.autojump():
        try:
            done = await _drive(r)
        finally:
            for robot in list(r.lives):  # quietly: the run is over
                net.crash(robot)
            for robot in reversed(list(r.lives)):
                await r.stop(robot)
    c = net.counters
    r.note(
        f"end: {'done' if done else 'not done'}; messages {c.sent} sent, {c.dropped} dropped, "
        f"{c.duplicated} duplicated, {c.delayed} delayed, {c.cut} cut, {c.held} held"
    )
    ch = r.checker
    return Outcome(
        plan,
        list(ch.violations),
        r.trace,
        clock.now(),
        c,
        done,
        r.failures,
        ch.double_ticks,
    )


def run_plan(plan: Plan) -> Outcome:
    """Run ``plan`` in a fresh event loop (the standard asyncio one: the clock reads its
    ready queue)."""
    loop = asyncio.new_event_loop()
    try:
        return loop.run_until_complete(_run(plan))
    finally:
        loop.close()
