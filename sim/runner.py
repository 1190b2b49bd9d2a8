"""Run a scenario: the simulation, an operator holding the mission tree, and the robots.

In-process mode puts every robot's actor system on one :class:`InProcessNetwork`;
distributed mode starts each robot in its own OS process over ZeroMQ (see
:mod:`sim.distributed`). Both record the same :class:`~sim.metrics.MissionResult`.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import msgspec
import numpy as np
import structlog

from btcap import State, Tree
from btcap.actors import ActorSystem, Clock, TimeSource
from btcap.sim.capabilities import robot_setup
from btcap.sim.grid import GridMap
from btcap.sim.manager import SimConfig, SimulationManager
from btcap.sim.messages import SIM_MESSAGES
from btcap.sim.metrics import MissionResult, collect
from btcap.sim.mission import mission_tree
from btcap.sim.model import RobotModel
from btcap.sim.scenario import Event, Scenario, check_scenario
from btcap.sim.store import MissionState, ObjectStore
from btcap.team.agent import Agent, AgentConfig
from btcap.team.capability import Capability
from btcap.team.protocol import protocol_registry
from btcap.transports import InProcessNetwork, MessageRegistry, Transport

__all__ = [
    "HostFactory",
    "InProcessHost",
    "Progress",
    "RobotHost",
    "agent_config",
    "agent_options",
    "registry",
    "run_scenario",
]

log = structlog.get_logger("sim")


def registry() -> MessageRegistry:
    """Every message of btcap plus the simulation's."""
    reg = protocol_registry()
    reg.register(*SIM_MESSAGES)
    return reg


def agent_options(s: Scenario) -> dict[str, Any]:
    """The scenario's ``agent:`` and ``allocation:`` blocks as AgentConfig keywords (their
    fields are named alike, so a new setting needs no mapping here)."""
    return {**msgspec.structs.asdict(s.agent), **msgspec.structs.asdict(s.allocation)}


def agent_config(s: Scenario) -> AgentConfig:
    return AgentConfig(**agent_options(s))


@dataclass
class Progress:
    """What a live display shows; updated as the mission runs."""

    time: float = 0.0
    summary: dict[str, Any] = field(default_factory=dict)
    tasks: dict[str, str] = field(default_factory=dict)
    present: dict[str, bool] = field(default_factory=dict)


@dataclass
class _World:
    scenario: Scenario
    clock: TimeSource
    state: MissionState
    manager: SimulationManager
    models: dict[str, RobotModel]
    marks: list[tuple[float, str, str]] = field(default_factory=list)


class RobotHost(Protocol):
    """Where robots live: tasks in this process, or OS processes (see sim.distributed)."""

    def transport(self, system_id: str) -> Transport: ...

    def start(self, name: str) -> None: ...

    def leave(self, name: str) -> None: ...

    def fail(self, name: str) -> None: ...

    def recover(self, name: str) -> None: ...

    def present(self) -> set[str]: ...

    async def aclose(self) -> None: ...


class InProcessHost:
    """Every robot an :class:`Agent` in this event loop, on one in-process network."""

    def __init__(self, s: Scenario, clock: TimeSource, reg: MessageRegistry, grid: GridMap) -> None:
        self.s = s
        self.clock = clock
        self.reg = reg
        self.grid = grid
        self.net = InProcessNetwork(reg)
        self.cfg = agent_config(s)
        self.models = s.models()
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._stop: dict[str, asyncio.Event] = {}
        self._up: set[str] = set()

    def transport(self, system_id: str) -> Transport:
        return self.net.transport(system_id)

    async def _life(self, name: str, stop: asyncio.Event) -> None:
        setup = robot_setup(name, self.models[_model_of(self.s, name)], self.grid)
        async with Agent(
            name,
            transport=self.net.transport(name),
            clock=self.clock,
            config=self.cfg,
            registry=self.reg,
            implementations=setup.implementations,
            actors=setup.actors,
        ):
            self._up.add(name)
            try:
                await stop.wait()
            finally:
                self._up.discard(name)

    def start(self, name: str) -> None:
        stop = self._stop[name] = asyncio.Event()
        before = self._tasks.get(name)
        self._tasks[name] = asyncio.get_running_loop().create_task(self._rejoin(name, stop, before))

    async def _rejoin(
        self, name: str, stop: asyncio.Event, before: asyncio.Task[None] | None
    ) -> None:
        if before is not None:  # a robot that left must be gone before it comes back
            await asyncio.gather(before, return_exceptions=True)
        await self._life(name, stop)

    def leave(self, name: str) -> None:
        ev = self._stop.get(name)
        if ev is not None:
            ev.set()

    def fail(self, name: str) -> None:
        self.net.isolate(name)
        self._up.discard(name)

    def recover(self, name: str) -> None:
        self.net.heal(name)
        self._up.add(name)

    def present(self) -> set[str]:
        return set(self._up)

    async def aclose(self) -> None:
        for ev in self._stop.values():
            ev.set()
        await asyncio.gather(*self._tasks.values(), return_exceptions=True)


HostFactory = Callable[[Scenario, TimeSource, MessageRegistry, GridMap], RobotHost]


async def run_scenario(
    scenario: Scenario,
    *,
    on_progress: Callable[[Progress], None] | None = None,
    progress_every_s: float = 0.1,
    clock: TimeSource | None = None,
    host: HostFactory | None = None,
) -> MissionResult:
    """Run the mission until it completes or its time limit passes.

    Robots are hosted in this process unless ``host`` says otherwise (see
    :func:`sim.distributed.run_distributed`).
    """
    s = check_scenario(scenario)
    clock = clock or Clock(s.speedup)
    reg = registry()
    grid = s.grid()
    rng = np.random.default_rng(s.seed)
    state = MissionState.scatter(grid, s.objects, s.contaminated_share, rng)
    manager = SimulationManager(
        state,
        SimConfig(s.sim.step_s, s.sim.delay_jitter, s.sim.failure_chance, s.seed),
    )
    models = s.models()
    for r in s.robots:
        manager.add_robot(r.name, models[r.model])
    w = _World(s, clock, state, manager, models)
    cfg = agent_config(s)
    robots: RobotHost = (host or InProcessHost)(s, clock, reg, grid)
    try:
        async with ActorSystem(
            "sim", transport=robots.transport("sim"), registry=reg, clock=clock
        ) as simsys:
            simsys.spawn(manager, SimulationManager.PATH)
            simsys.spawn(ObjectStore(state), ObjectStore.PATH)
            async with Agent(
                "operator",
                transport=robots.transport("operator"),
                clock=clock,
                config=cfg,
                registry=reg,
            ) as operator:
                operator.team.subscribe(
                    lambda ev, robot: w.marks.append((clock.now(), ev.value, robot))
                )
                for r in s.initially_present():
                    manager.robot_up(r.name)
                    robots.start(r.name)
                expected = len(s.initially_present())
                await _until(lambda: len(operator.team.members) >= expected, 60.0)

                def apply(e: Event) -> None:
                    if e.kind == "join":
                        manager.robot_up(e.robot)
                        robots.start(e.robot)
                    elif e.kind == "leave":
                        manager.robot_down(e.robot)
                        robots.leave(e.robot)
                    elif e.kind == "fail":
                        robots.fail(e.robot)
                        manager.robot_down(e.robot)
                        w.marks.append((clock.now(), "down", e.robot))

                        async def recover() -> None:
                            await clock.sleep(e.duration)
                            robots.recover(e.robot)
                            manager.robot_up(e.robot)
                            w.marks.append((clock.now(), "up", e.robot))

                        simsys.start_task(recover(), name=f"recover {e.robot}")

                async def events() -> None:
                    t0 = clock.now()
                    for e in sorted(s.events, key=lambda e: e.at):
                        await clock.sleep_until(t0 + e.at)
                        apply(e)

                tree = mission_tree(object_workers=s.object_workers)
                operator.mission(tree)
                started = clock.now()
                ev_task = simsys.start_task(events(), name="scenario events")
                final = await _run_mission(
                    tree, w, started, cfg.tick_hz, on_progress, progress_every_s, robots
                )
                ev_task.cancel()
                result = collect(
                    s, w.state, manager, tree, operator, started, clock.now(), final, w.marks
                )
                await tree.shutdown()
    finally:
        await robots.aclose()
    return result


def _model_of(s: Scenario, name: str) -> str:
    return next(r.model for r in s.robots if r.name == name)


async def _until(cond: Callable[[], bool], limit_s: float) -> None:
    for _ in range(int(limit_s / 0.01)):
        if cond():
            return
        await asyncio.sleep(0.01)


async def _run_mission(
    tree: Tree,
    w: _World,
    started: float,
    rate_hz: float,
    on_progress: Callable[[Progress], None] | None,
    every_s: float,
    robots: RobotHost,
) -> State:
    clock = w.clock
    limit = w.scenario.time_limit_s
    period = 1.0 / rate_hz
    deadline = clock.now()
    next_report = 0.0
    state = State.RUNNING
    loop = asyncio.get_running_loop()
    while True:
        state = tree.tick()
        now = clock.now()
        if on_progress is not None and loop.time() >= next_report:
            next_report = loop.time() + every_s
            on_progress(_progress(tree, w, now - started, robots))
        if state in (State.SUCCEEDED, State.FAILED, State.ERROR) or now - started > limit:
            if on_progress is not None:
                on_progress(_progress(tree, w, now - started, robots))
            return state
        deadline += period
        if deadline < now - period:
            deadline = now
        await clock.sleep_until(deadline)


def _progress(tree: Tree, w: _World, t: float, robots: RobotHost) -> Progress:
    tasks: dict[str, str] = {}
    for n in tree.nodes():
        if isinstance(n, Capability) and n.execution is not None:
            tasks[n.execution.robot] = f"{type(n).INTERFACE.name} ({n.path.rsplit('/', 2)[-2]})"
    up = robots.present()
    present = {r.name: r.name in up and w.manager.robots[r.name].up for r in w.scenario.robots}
    return Progress(t, w.state.summary(), tasks, present)
