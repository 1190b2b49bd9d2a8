"""Run a scenario: the simulation, an operator holding the mission tree, and the robots.

In-process mode puts every robot's actor system on one :class:`InProcessNetwork` (see
:class:`~btcap.sim.running.hosts.InProcessHost`); distributed mode starts each robot in its own
OS process over ZeroMQ (see :mod:`btcap.sim.running.distributed`). Both record the same
:class:`~btcap.sim.running.metrics.MissionResult`, including every robot that crashed.
"""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import anyio
import numpy as np

from btcap import State, Tree
from btcap.actors import ActorSystem, Clock, ManualClock, TimeSource
from btcap.bt.files.btlog import BtlogRecorder
from btcap.bt.state import DONE
from btcap.monitor import Monitor
from btcap.sim.mission.carryplan import carrier_pace
from btcap.sim.mission.idplan import identifier_pace
from btcap.sim.mission.paper import mission_tree
from btcap.sim.mission.pool import pool_lanes, pool_mission_tree, spare_explorers, standby_lanes
from btcap.sim.mission.scenario import Event, Scenario, check_scenario
from btcap.sim.running.hosts import (
    SIM_SYSTEM,
    InProcessHost,
    RobotHost,
    agent_config,
    registry,
)
from btcap.sim.running.metrics import MissionLog, MissionResult, RobotError, collect
from btcap.sim.running.worldfeed import WorldFeed
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.store import MissionState, ObjectStore
from btcap.team.capabilities.capability import Capability
from btcap.team.membership.membership import TeamEvent
from btcap.team.runtime.agent import Agent
from btcap.transports import MessageRegistry
from btcap.transports.log import get_logger

__all__ = [
    "HostFactory",
    "Progress",
    "run_fast",
    "run_scenario",
]

log = get_logger(__name__)

#: Object lanes of the pool mission at most (one per object the scenario scatters up to
#: this; beyond, an object waits for a lane to come free).
MAX_OBJECT_LANES = 64
#: Seconds the robots present at the start have to join the team: of the wall on a real
#: clock, of the clock on a virtual one (where wall time must decide nothing).
TEAM_FORMS_S = 60.0


@dataclass
class Progress:
    """What a live display shows; updated as the mission runs."""

    time: float = 0.0
    summary: dict[str, Any] = field(default_factory=dict)
    tasks: dict[str, str] = field(default_factory=dict)
    present: dict[str, bool] = field(default_factory=dict)


HostFactory = Callable[[Scenario, TimeSource, MessageRegistry, GridMap], RobotHost]


async def run_fast(scenario: Scenario, **options: Any) -> MissionResult:
    """:func:`run_scenario` on a virtual clock that jumps to the next deadline whenever
    every actor waits: the mission takes as long as its computation, not its simulated
    time, and the same scenario and seed give the same result."""
    clock = ManualClock()
    async with clock.autojump():
        return await run_scenario(scenario, clock=clock, **options)


async def run_scenario(
    scenario: Scenario,
    *,
    on_progress: Callable[[Progress], None] | None = None,
    progress_every_s: float = 0.1,
    progress_clock: Literal["wall", "mission"] = "wall",
    clock: TimeSource | None = None,
    host: HostFactory | None = None,
    stop: anyio.Event | None = None,
    monitor: Monitor | None = None,
    ros2: bool = False,
    btlog: Path | None = None,
    ros1: bool = False,
) -> MissionResult:
    """Run the mission until it completes, its time limit passes or ``stop`` is set (the
    result then says ``interrupted``).

    ``on_progress`` is called at the end and every ``progress_every_s`` seconds of wall
    time (for a live display) or, with ``progress_clock="mission"``, of mission time (for
    log lines, which then fall at the same instants in every run of a seed).

    Robots are hosted in this process unless ``host`` says otherwise (see
    :func:`sim.running.distributed.run_distributed`); ``ros2`` hosts them in this process with
    their bodies reached only through ROS 2 interfaces the simulation serves (see
    :mod:`btcap.sim.ros2`; rclpy is imported in a thread as the run starts), as does a
    scenario with a ``ros`` block on a real clock (its settings; ``ros2`` alone: their
    defaults; the fast mode leaves the block aside); ``ros1`` (or the block's ``backend:
    ros1``) puts them behind ROS 1 as the paper did (:mod:`btcap.sim.ros1`). A robot
    that crashes is logged, taken out of the simulation and listed in the result's
    ``errors``; the mission goes on.

    A ``monitor`` is shown the operator (its membership view), the mission tree and every
    robot hosted in this process; it is detached when the mission ends, so it keeps the
    last states rather than the shutdown, and told how the mission ended.

    ``btlog``: the mission tree's run is written there as BehaviorTree.CPP's file logger
    writes one (:class:`~btcap.bt.files.btlog.BtlogRecorder`), for Groot2 to replay.
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
    # A scenario's block puts its robots behind ROS 2 on the wall clock; on virtual time
    # (the fast mode, `btcap sweep`) DDS cannot follow, and they are reached directly.
    if ros1 or ros2 or (s.ros is not None and math.isfinite(clock.speedup)):
        if host is not None:
            raise ValueError("run_scenario: ros1/ros2 host the robots themselves; give no host")
        if ros1 or (not ros2 and s.ros is not None and s.ros.backend == "ros1"):
            from btcap.sim.ros1.host import Ros1Host

            host = functools.partial(Ros1Host, manager=manager)
        else:
            from btcap.sim.ros2.host import Ros2Host

            host = functools.partial(Ros2Host, manager=manager)
    mlog = MissionLog()
    cfg = agent_config(s)
    async with (
        (host or InProcessHost)(s, clock, reg, grid) as robots,
        ActorSystem(
            SIM_SYSTEM, transport=robots.transport(SIM_SYSTEM), registry=reg, clock=clock
        ) as simsys,
    ):
        simsys.spawn(manager, SimulationManager.PATH)
        feed: WorldFeed | None = None
        if monitor is not None:
            monitor.follow(clock)  # on virtual time: a run's recording is reproducible too
            # The simulated world too (btcap.sim.running.worldfeed): the map, then robots and
            # objects step by step (poses every 2 s at most), for Foxglove's 3D panel.
            present = {r.name for r in s.initially_present()}
            feed = WorldFeed(manager, absent=[r.name for r in s.robots if r.name not in present])
            monitor.emit(feed.map_event(clock.now()))
            monitor.add_source(feed.sample, last=feed.last)
            if isinstance(robots, InProcessHost):
                robots.on_agent = monitor.add_agent
        simsys.spawn(ObjectStore(state), ObjectStore.PATH)
        operator = Agent(
            "operator",
            transport=robots.transport("operator"),
            clock=clock,
            config=cfg,
            registry=reg,
            missions=True,  # the strategy's modules imported as it starts, off the loop
        )
        if math.isinf(clock.speedup):  # its life numbered by the run, as the robots': same ids
            operator.team.incarnation = 1
        async with operator:
            if monitor is not None:
                monitor.add_agent(operator)
            operator.team.subscribe(lambda ev, robot: mlog.mark(clock.now(), ev.value, robot))

            def verdict(ev: TeamEvent, robot: str) -> None:
                # The sim follows the team: the lease's expiry and the sim's view agree.
                if ev is TeamEvent.FAILED or ev is TeamEvent.LEFT:
                    manager.team_verdict(robot, gone=True)
                elif ev is TeamEvent.JOINED:
                    manager.team_verdict(robot, gone=False, present=robot in robots.present())

            operator.team.subscribe(verdict)
            for r in s.initially_present():
                manager.robot_up(r.name)
                robots.start(r.name)
            stop = stop or anyio.Event()
            await _team_forms(
                operator, {r.name for r in s.initially_present()}, robots, clock, stop
            )

            def apply(e: Event) -> None:
                mlog.applied[e.kind] += 1
                if e.kind == "join":
                    manager.robot_up(e.robot)
                    robots.start(e.robot)
                    if feed is not None:
                        feed.joined(e.robot)
                elif e.kind == "leave":
                    manager.robot_down(e.robot)
                    robots.leave(e.robot)
                elif e.kind == "fail":
                    robots.fail(e.robot)
                    manager.robot_down(e.robot)
                    mlog.mark(clock.now(), "down", e.robot)

                    async def recover() -> None:
                        await clock.sleep(e.duration)
                        robots.recover(e.robot)
                        manager.robot_up(e.robot)
                        mlog.mark(clock.now(), "up", e.robot)

                    simsys.start_task(recover(), name=f"recover {e.robot}")

            async def events() -> None:
                t0 = clock.now()
                for e in sorted(s.events, key=lambda e: e.at):
                    await clock.sleep_until(t0 + e.at)
                    apply(e)

            tree = _mission(s, grid)
            operator.mission(tree)
            tree.observe(mlog)
            if monitor is not None:
                monitor.add_tree(tree, robot="operator")
            started = clock.now()
            ev_task = simsys.start_task(events(), name="scenario events")
            watch = _Watch(tree, s, manager, robots, mlog, started, on_progress, progress_every_s)
            watch.mission_clock = progress_clock == "mission"
            watch.stop = stop
            with BtlogRecorder(tree, btlog) if btlog else contextlib.nullcontext():
                final = await tree.run(cfg.tick_hz, until=watch)
            ev_task.cancel()
            if stop.is_set():
                log.info("sim.interrupted", scenario=s.name)  # asked for: no warning
            elif final not in DONE:
                log.warning("sim.time_limit", scenario=s.name, limit_s=s.time_limit_s)
            result = collect(
                s,
                state,
                manager,
                tree,
                operator,
                mlog,
                robots.errors,
                started,
                clock.now(),
                final,
                interrupted=stop.is_set() and final not in DONE,
            )
            if monitor is not None:
                monitor.detach()
                monitor.finish(*_outcome(result, s))
            await tree.shutdown()
    return result


def _mission(s: Scenario, grid: GridMap) -> Tree:
    """The scenario's mission tree; the pool mission's lanes: see :func:`pool_lanes`,
    its identifiers' plan priced at :func:`identifier_pace`."""
    if s.mission == "paper":
        return mission_tree(object_workers=s.object_workers)
    models = s.models()
    team = [models[r.model] for r in s.robots]
    explore, identify, carry = pool_lanes(team)
    return pool_mission_tree(
        explorers=explore,
        identifiers=identify,
        carriers=carry,
        standby=standby_lanes(team),
        spare_explorers=spare_explorers(team),
        objects=min(s.objects, MAX_OBJECT_LANES),
        grid=grid,
        near_m=max((m.operation("explore").radius_m for m in team if m.can("explore")), default=0),
        pace=identifier_pace(team, grid.cell_size_m),
        carry_pace=carrier_pace(team),
    )


def _outcome(result: MissionResult, s: Scenario) -> tuple[str, str]:
    """How a monitor says the mission ended: (result, a line for a person)."""
    after = f"after {result.mission_time_s:.0f} s"
    if result.completed:
        return "succeeded", f"mission succeeded {after}"
    if result.interrupted:
        return "stopped", f"mission stopped {after} (interrupted)"
    if result.timed_out:
        return "failed", f"mission failed: time limit of {s.time_limit_s:g} s reached"
    return "failed", f"mission failed {after}"


async def _team_forms(
    operator: Agent, expected: set[str], robots: RobotHost, clock: TimeSource, stop: anyio.Event
) -> None:
    """Wait until the robots present at the start are team members (or crashed); a robot
    still missing after :data:`TEAM_FORMS_S` is an error of the run, not a silent wait."""

    def missing() -> set[str]:
        crashed = {e.robot for e in robots.errors}
        return expected - crashed - operator.team.alive()

    # Polled on the mission's clock (about every 10 ms of wall time on a real one), so a
    # virtual clock's run does not depend on how fast real time passes.
    virtual = not math.isfinite(clock.speedup)
    poll = 0.05 if virtual else 0.01 * clock.speedup
    deadline = clock.now() + TEAM_FORMS_S
    with anyio.move_on_after(math.inf if virtual else TEAM_FORMS_S):
        while missing() and not stop.is_set():
            if virtual and clock.now() >= deadline:
                break
            await clock.sleep(poll)
        else:
            return
    for robot in sorted(missing()):
        log.error("sim.robot_absent", robot=robot, waited_s=TEAM_FORMS_S)
        robots.errors.append(
            RobotError(clock.now(), robot, f"did not join the team within {TEAM_FORMS_S:g} s")
        )


class _Watch:
    """Tree.run's stop condition for a mission, called after every tick: reports
    progress, takes crashed robots out of the simulation, and stops at a result or at
    the scenario's time limit."""

    def __init__(
        self,
        tree: Tree,
        s: Scenario,
        manager: SimulationManager,
        robots: RobotHost,
        mlog: MissionLog,
        started: float,
        on_progress: Callable[[Progress], None] | None,
        every_s: float,
    ) -> None:
        self.tree = tree
        self.s = s
        self.manager = manager
        self.robots = robots
        self.mlog = mlog
        self.started = started
        self.on_progress = on_progress
        self.every_s = every_s
        self.next_report = 0.0
        self.crashes_seen = 0
        self.stop: anyio.Event | None = None
        self.mission_clock = False

    def __call__(self, state: State) -> bool:
        now = self.tree.clock.now() - self.started
        errors = self.robots.errors
        if self.crashes_seen < len(errors):
            present = self.robots.present()
            for e in errors[self.crashes_seen :]:
                # A crashed robot does no more work; one only slow to join is still there.
                if e.robot not in present:
                    self.manager.robot_down(e.robot)
                    self.mlog.mark(e.time, "crashed", e.robot)
            self.crashes_seen = len(errors)
        done = state in DONE or now > self.s.time_limit_s
        done = done or (self.stop is not None and self.stop.is_set())
        if self.on_progress is not None:
            at = now if self.mission_clock else anyio.current_time()
            if done or at >= self.next_report:
                self.next_report = at + self.every_s
                self.on_progress(self._progress(now))
        return done

    def _progress(self, t: float) -> Progress:
        tasks: dict[str, str] = {}
        for n in self.tree.nodes():
            if isinstance(n, Capability) and n.execution is not None:
                where = n.path.rsplit("/", 2)[-2]
                tasks[n.execution.robot] = f"{type(n).INTERFACE.name} ({where})"
        up = self.robots.present()
        present = {r.name: r.name in up and self.manager.robots[r.name].up for r in self.s.robots}
        return Progress(t, self.manager.state.summary(), tasks, present)
