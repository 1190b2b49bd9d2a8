"""Shared helpers for the capability-layer tests: a probed implementation, agent teams on
an in-process network, and bounded polling (never fixed long sleeps)."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
from collections import Counter
from collections.abc import AsyncIterator, Callable, Iterable, Iterator, Mapping
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from typing import Any

from btcap import Leaf, Port, ReactiveSequence, State, Tree
from btcap.actors import Actor, ActorSystem, Clock, ManualClock, TimeSource
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation, Precondition
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.background import Background, start_in_background
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

#: Clock seconds run SPEEDUP times faster than the wall in these tests.
SPEEDUP = 10.0

#: A capability whose implementation echoes its input every tick and runs until told to
#: stop (or for a fixed number of ticks): ``y = x * k``, ``ticks`` counts the run's ticks.
COUNT = CapabilityInterface(
    "Count",
    inputs={"x": int, "stop": Port(bool, False)},
    outputs={"y": int, "ticks": int, "robot": str},
    description="echo x*k every tick until stop",
)


def config(**over: Any) -> AgentConfig:
    """Fast protocol timing (clock seconds; divide by SPEEDUP for wall time)."""
    base: dict[str, Any] = {
        "tick_hz": 20.0,
        "heartbeat_s": 0.1,
        # Generous against false failures on a loaded machine (200 ms of wall time).
        "failure_timeout_s": 2.0,
        "lease_s": 2.0,
        "keepalive_s": 0.2,
        # Auctions close as soon as everyone answered; the window only bounds silence, so
        # it is long enough that a loaded machine never turns a late answer into none.
        "auction_window_s": 20.0,
        "award_timeout_s": 1.0,
    }
    base.update(over)
    return AgentConfig(**base)


@dataclass
class Probe:
    """What the implementations of one test did, by robot and by run."""

    ticks: Counter[str] = field(default_factory=Counter)
    unticks: Counter[str] = field(default_factory=Counter)
    shutdowns: Counter[str] = field(default_factory=Counter)
    setups: Counter[str] = field(default_factory=Counter)
    first_x: dict[int, tuple[str, int]] = field(default_factory=dict)  # run -> (robot, x)
    active: dict[str, set[int]] = field(default_factory=dict)  # robot -> runs ticked, not ended
    violations: list[str] = field(default_factory=list)
    runs: Iterator[int] = field(default_factory=lambda: itertools.count(1))

    def live(self, robot: str) -> int:
        """Runs of ``robot`` set up and not yet shut down."""
        return self.setups[robot] - self.shutdowns[robot]

    def start(self, robot: str, run: int) -> None:
        mine = self.active.setdefault(robot, set())
        others = mine - {run}
        if others:
            self.violations.append(f"{robot} ticks run {run} while {sorted(others)} active")
        mine.add(run)

    def end(self, robot: str, run: int) -> None:
        self.active.get(robot, set()).discard(run)


class Echo(Leaf):
    """``y = x * k`` and one more tick, every tick; always succeeds."""

    INPUTS = {"x": int}
    OUTPUTS = {"y": int, "ticks": int, "robot": str}

    def __init__(self, probe: Probe, robot: str, run: int, k: int) -> None:
        super().__init__("echo")
        self.probe, self.robot, self.run, self.k = probe, robot, run, k
        self.count = 0

    def on_setup(self) -> None:
        self.probe.setups[self.robot] += 1

    def on_tick(self) -> State:
        self.probe.start(self.robot, self.run)
        if self.count == 0:
            self.probe.first_x[self.run] = (self.robot, self.inputs["x"])
        self.count += 1
        self.probe.ticks[self.robot] += 1
        self.outputs.update(y=self.inputs["x"] * self.k, ticks=self.count, robot=self.robot)
        return State.SUCCEEDED

    def on_shutdown(self) -> None:
        self.probe.shutdowns[self.robot] += 1
        self.probe.end(self.robot, self.run)


class Finish(Leaf):
    """Running until the ``stop`` input is set or ``after`` ticks have passed."""

    INPUTS = {"stop": Port(bool, False)}

    def __init__(self, probe: Probe, robot: str, run: int, after: int | None) -> None:
        super().__init__("finish")
        self.probe, self.robot, self.run, self.after = probe, robot, run, after
        self.count = 0

    def on_tick(self) -> State:
        self.count += 1
        if self.inputs["stop"] or (self.after is not None and self.count >= self.after):
            self.probe.end(self.robot, self.run)
            return State.SUCCEEDED
        return State.RUNNING

    def on_untick(self) -> None:
        self.probe.unticks[self.robot] += 1


def count_impl(
    robot: str,
    cost: float | Callable[[Mapping[str, Any]], float | None],
    probe: Probe,
    *,
    k: int = 1,
    after: int | None = None,
    name: str | None = None,
    interface: CapabilityInterface = COUNT,
    preconditions: tuple[Precondition, ...] = (),
) -> Implementation:
    """An implementation of ``interface`` (shaped like COUNT) on ``robot`` bidding ``cost``."""

    def build() -> Tree:
        run = next(probe.runs)
        ib, ob = interface.bridge_types()
        i, e, f, o = (
            ib(name="in"),
            Echo(probe, robot, run, k),
            Finish(probe, robot, run, after),
            ob(name="out"),
        )
        t = Tree(ReactiveSequence("impl", children=[i, e, o, f]))
        t.wire(i, "x", e, "x")
        t.wire(i, "stop", f, "stop")
        for port in ("y", "ticks", "robot"):
            t.wire(e, port, o, port)
        return t

    bid = cost if callable(cost) else (lambda _inputs, c=float(cost): c)
    return Implementation(
        name or f"{interface.name.lower()}-{robot}", interface, build, preconditions, bid
    )


#: The manual clock of the team a test runs, if any: time then passes only in ``step``.
_manual: ManualClock | None = None


async def step(wall: float = 0.005) -> None:
    """Let ``wall`` seconds pass as the team sees them. On a team's manual clock that is
    ``wall * SPEEDUP`` clock seconds, which autojump skips as soon as everything else
    waits too: the outcome never depends on how loaded the machine is."""
    if _manual is None:
        await asyncio.sleep(wall)
    else:
        await _manual.sleep(wall * SPEEDUP)


async def until(cond: Callable[[], bool], what: str = "condition", *, limit: int = 2000) -> None:
    """Check ``cond`` every step (bounded); the test's fail_after is the real limit."""
    for _ in range(limit):
        if cond():
            return
        await step()
    raise AssertionError(f"timed out waiting for {what}")


async def tick_until(
    tree: Tree, cond: Callable[[State], bool], what: str = "state", *, limit: int = 2000
) -> State:
    """Tick ``tree`` every step until ``cond(state)``; returns that state."""
    for _ in range(limit):
        state = tree.tick()
        if cond(state):
            return state
        await step()
    raise AssertionError(f"tree {tree.name!r}: timed out waiting for {what} (last {state})")


class Team:
    """Agents on one in-process network. Each agent lives in its own task (an actor system
    holds a task group, so systems sharing one task must exit in reverse order), so any
    robot can leave at any time."""

    def __init__(self, *, real_time: bool = False, **cfg: Any) -> None:
        self.net = InProcessNetwork(protocol_registry())
        self.clock: TimeSource = Clock(speedup=SPEEDUP) if real_time else ManualClock()
        self.cfg = cfg
        self.agents: dict[str, Agent] = {}
        #: What each agent's membership reported, in order (robot -> [(event, member)]).
        self.events: dict[str, list[tuple[TeamEvent, str]]] = {}
        self._lives: dict[str, Background] = {}

    async def add(self, robot: str, impls: Iterable[Implementation] = (), **cfg: Any) -> Agent:
        options = {**self.cfg, **cfg}
        strategy = options.get("strategy")
        if strategy is not None and not isinstance(strategy, str):  # a strategy object
            del options["strategy"]
        agent = Agent(
            robot,
            transport=self.net.transport(robot),
            clock=self.clock,
            implementations=impls,
            config=config(**options),
            strategy=strategy,
        )
        log = self.events.setdefault(robot, [])
        agent.team.subscribe(lambda event, member: log.append((event, member)))
        self._lives[robot] = await start_in_background(agent)  # raises what entry raised
        self.agents[robot] = agent
        return agent

    def seen(self, robot: str, member: str) -> list[TeamEvent]:
        """What ``robot``'s membership reported of ``member`` so far."""
        return [e for e, r in self.events[robot] if r == member]

    async def remove(self, robot: str) -> None:
        """The robot leaves on purpose (its agent exits, saying goodbye)."""
        self.agents.pop(robot)
        await self._lives.pop(robot).stop()

    async def close(self) -> None:
        for robot in reversed(list(self._lives)):
            await self.remove(robot)

    def __getitem__(self, robot: str) -> Agent:
        return self.agents[robot]

    async def origin_and_executor(self, probe: Probe) -> tuple[Agent, Agent]:
        """Robot "a" with no implementation and "b" running COUNT for it, converged."""
        a = await self.add("a")
        b = await self.add("b", [count_impl("b", 1.0, probe)])
        await self.converged()
        return a, b

    async def converged(self, identity: str = COUNT.identity) -> None:
        """Every agent sees every other as alive, and knows what each provides."""
        robots = set(self.agents)

        def ok() -> bool:
            for a in self.agents.values():
                if a.team.alive() != robots:
                    return False
                want = {
                    r
                    for r, b in self.agents.items()
                    if b.repository.local_implementations(identity.split("(", 1)[0], identity)
                }
                if a.repository.providers(identity) != want:
                    return False
            return True

        await until(ok, f"team {sorted(robots)} to converge")


@asynccontextmanager
async def team(**cfg: Any) -> AsyncIterator[Team]:
    """Agents on a manual clock (``real_time=True``: a sped-up wall clock, for the few
    tests whose subject is wall-clock behaviour)."""
    global _manual
    t = Team(**cfg)
    async with contextlib.AsyncExitStack() as stack:
        if isinstance(t.clock, ManualClock):
            _manual = await stack.enter_async_context(t.clock.autojump())
        try:
            yield t
        finally:
            try:
                await t.close()
            finally:
                _manual = None


@asynccontextmanager
async def silent_member(
    net: InProcessNetwork,
    robot: str,
    impls: Iterable[Implementation],
    clock: TimeSource,
    actors: Mapping[str, Actor] | None = None,
    **cfg: Any,
) -> AsyncIterator[ActorSystem]:
    """A robot that heartbeats and advertises implementations but never answers calls for
    bids (it has no mission control): auctions must not wait for it forever. ``actors``
    are spawned beside (e.g. a scripted mission control)."""
    c = config(**cfg)
    system = ActorSystem(
        robot, transport=net.transport(robot), registry=protocol_registry(), clock=clock
    )
    async with system:
        members = Membership(
            robot,
            heartbeat_s=c.heartbeat_s,
            failure_timeout_s=c.failure_timeout_s,
            repo_version=lambda: repo.version,
        )
        repo = CapabilityRepository(robot, team=members)
        repo.extend(impls)
        system.spawn(members, Membership.PATH)
        system.spawn(repo, CapabilityRepository.PATH)
        for path, actor in (actors or {}).items():
            system.spawn(actor, path)
        yield system
