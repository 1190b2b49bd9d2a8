"""The simulation manager: ground truth of the world, answering robots after delays.

Robots ask it to move and to explore, identify or decontaminate. Moves end when the
vectorised world step brings the robot to its goal; operations end after the robot
model's duration, randomised, and may fail with a set chance (seeded). Answers are
deferred replies, so the manager serves every robot at once.

The draws are common random numbers: each operation's jitter and failure come from a
stream of their own, keyed by what the operation is (explore at this cell, identify or
decontaminate this object) and how many such attempts ran to their end before, never from
one stream shared by the run. Whichever robot does it and whenever, the same operation
gets the same draw, so two runs of a seed that award the work differently differ by the
awards, not by a reshuffle of every later draw (what comparing strategies needs).

Each robot's body hears where it is and what it does as it happens (a
:class:`~btcap.sim.world.messages.PositionUpdate` for every cell it drives into and every
operation that starts, begins its timed work or ends), so what it bids for the work it
holds is what finishing costs from here, not from where it started.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from btcap.actors import Actor, TimeSource, handler
from btcap.sim.world.distance import Cell
from btcap.sim.world.messages import MoveTo, Operate, PositionUpdate, SimResult, StopRobot
from btcap.sim.world.model import RobotModel
from btcap.sim.world.motion import World
from btcap.sim.world.store import MissionState
from btcap.transports import Address
from btcap.transports.log import get_logger

__all__ = ["SimConfig", "SimEvent", "SimulationManager"]

log = get_logger(__name__)


@dataclass(slots=True)
class SimConfig:
    """Randomness and pace of the simulation (clock seconds)."""

    step_s: float = 0.5
    delay_jitter: float = 0.2  # durations are drawn from duration x U(1 - j, 1 + j)
    failure_chance: float = 0.05
    seed: int = 0


@dataclass(slots=True)
class SimEvent:
    """A line of the mission's timeline: who did what, from when to when."""

    robot: str
    kind: str  # move | explore | identify | decontaminate
    start: float
    end: float | None = None
    ok: bool | None = None
    target: int = -1
    detail: str = ""


@dataclass(slots=True)
class _Op:
    """An operation in progress: its reply, its timeline line, whether it holds an object."""

    fut: asyncio.Future[SimResult]
    event: SimEvent
    target: int
    key: tuple[int, int, int]  # what the operation is, for its draws (see ``_key``)
    carrying: bool = False
    working: bool = False  # its timed work has begun (decontaminate: at the decon area)


@dataclass(slots=True)
class _Robot:
    name: str
    index: int
    model: RobotModel
    up: bool = True
    move: asyncio.Future[SimResult] | None = None
    move_event: SimEvent | None = None
    busy: list[_Op] = field(default_factory=list)
    carrying: int = -1


_OPS = ("explore", "identify", "decontaminate")
_STREAM = 0x0B7CA9  # this module's tag in the seed sequence of every draw


def _key(op: str, target: int, cell: Cell) -> tuple[int, int, int]:
    """What an operation is, for its draws: exploring at ``cell``, or working on object
    ``target``; not who does it, nor when."""
    if op == "explore":
        return (0, int(cell[0]), int(cell[1]))
    return (_OPS.index(op), target, 0)


class SimulationManager(Actor):
    """One per simulation; lives beside the :class:`~sim.world.store.ObjectStore`."""

    PATH = "manager"

    def __init__(self, state: MissionState, config: SimConfig | None = None) -> None:
        super().__init__()
        self.state = state
        self.config = config or SimConfig()
        self.world = World(state.grid)
        #: Attempts that ran to their end, per operation key (see :meth:`draw`).
        self._attempts: dict[tuple[int, int, int], int] = {}
        self.robots: dict[str, _Robot] = {}
        self.events: list[SimEvent] = []
        self._clock: TimeSource | None = None
        self._by_index: list[_Robot] = []  # world index -> robot
        self._cells = self.world.positions  # as the bodies were last told
        #: Where the robots' state goes instead of their bodies' actors, if set: the
        #: simulator behind ROS 2 publishes it (see :mod:`btcap.sim.ros2`).
        self.on_position: Callable[[PositionUpdate], None] | None = None

    def add_robot(self, name: str, model: RobotModel, cell: Cell | None = None) -> None:
        if name in self.robots:
            raise ValueError(f"robot {name!r} is already in the simulation")
        i = self.world.add_robot(
            cell or self.state.grid.start, speed_mps=model.speed_mps, cost_factor=model.cost_factor
        )
        self.robots[name] = r = _Robot(name, i, model)
        self._by_index.append(r)
        self._cells = self.world.positions

    @property
    def cells(self) -> NDArray[np.intp]:
        """``(n, 2)`` cells of all robots as of the last step, by world index (the array
        the step computed: read it, do not change it)."""
        return self._cells

    def position(self, name: str) -> Cell:
        return self.world.position(self.robots[name].index)

    def now(self) -> float:
        # The clock is kept, so operations ending as the system stops still get a time.
        return self._clock.now() if self._clock is not None else self.system.clock.now()

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self._clock = self.system.clock
        self.start_task(self._run(), name="sim steps")

    async def _run(self) -> None:
        clock = self.system.clock
        dt = self.config.step_s
        deadline = clock.now()
        while True:
            deadline += dt
            await clock.sleep_until(deadline)
            arrived = self.world.step(dt)
            told: set[int] = set()
            for r in self.robots.values():
                if r.move is not None and r.index in arrived:
                    self._end_move(r, True, "arrived")  # tells the body
                    told.add(r.index)
            self._tell_moved(told)

    def _tell_moved(self, told: set[int]) -> None:
        """Tell each robot that drove into another cell in this step where it is now (one
        comparison over all robots), unless it was ``told`` already."""
        cells, before = self.world.positions, self._cells
        self._cells = cells
        n = len(before)  # robots added since have not moved yet
        for i in np.flatnonzero((cells[:n] != before).any(axis=1)).tolist():
            if i not in told:
                self._tell_position(self._by_index[i])

    # -- failures (driven by scenarios) -----------------------------------------------
    def robot_down(self, name: str, why: str = "robot down") -> None:
        """The robot fails: it stops, drops what it carries, its operations fail."""
        r = self.robots[name]
        r.up = False
        self.world.deactivate(r.index)
        if r.move is not None:
            self._end_move(r, False, why)
        self._abort(r, why)
        if r.carrying >= 0:
            self.state.drop(r.carrying, self.position(name))
            r.carrying = -1

    def team_verdict(self, name: str, gone: bool, *, present: bool = True) -> None:
        """What the team decided about ``name`` (from its membership): a robot declared
        failed or gone is taken down here too, so no operation of it completes and its body
        stays where it was; one that is back (and ``present``, i.e. not taken out by the
        scenario) works again. Names that are not simulated robots are ignored."""
        r = self.robots.get(name)
        if r is None:
            return
        if gone:
            if r.up:
                log.info("sim.robot_gone", robot=name, busy=len(r.busy), moving=r.move is not None)
                self.robot_down(name, "declared gone by the team")
        elif present and not r.up:
            self.robot_up(name)

    def robot_up(self, name: str) -> None:
        r = self.robots[name]
        r.up = True
        self.world.activate(r.index)

    # -- requests ---------------------------------------------------------------------
    def draw(
        self, op: str, target: int, cell: Cell, attempt: int | None = None
    ) -> tuple[float, bool]:
        """The duration factor and whether it fails, for the next attempt at ``op`` on
        object ``target`` (explore: at ``cell``), by any robot: drawn from a stream of its
        own (the seed, what the operation is and how many attempts at it ran to their
        end), so it does not depend on what was drawn before. An attempt cut short
        (superseded, stopped) leaves its draw to the next. ``attempt``: the draw of the
        attempt after that many ended, instead of the next."""
        key = _key(op, target, cell)
        n = self._attempts.get(key, 0) if attempt is None else attempt
        rng = np.random.default_rng([_STREAM, self.config.seed, *key, n])
        j = self.config.delay_jitter
        factor = float(rng.uniform(1 - j, 1 + j))
        return factor, bool(rng.random() < self.config.failure_chance)

    def _robot(self, name: str) -> _Robot | None:
        r = self.robots.get(name)
        return r if r is not None and r.up else None

    def _refuse(self, name: str, why: str) -> SimResult:
        cell = self.position(name) if name in self.robots else (0, 0)
        return SimResult(False, cell, why)

    @handler
    def on_move(self, msg: MoveTo) -> SimResult | asyncio.Future[SimResult]:
        r = self._robot(msg.robot)
        if r is None:
            return self._refuse(msg.robot, "unknown or failed robot")
        goal = (int(msg.goal[0]), int(msg.goal[1]))
        if not self.state.grid.is_free(goal):
            return self._refuse(msg.robot, f"goal {goal} is not a free cell")
        if r.move is not None:
            self._end_move(r, False, "superseded")
        self._abort(r, "superseded")  # one body: driving off abandons any operation
        if self.position(msg.robot) == goal:
            return SimResult(True, goal, "already there")
        try:
            self.world.set_goal(r.index, goal)
        except ValueError as exc:
            return self._refuse(msg.robot, str(exc))
        fut: asyncio.Future[SimResult] = asyncio.get_running_loop().create_future()
        r.move = fut
        r.move_event = self._event(r.name, "move", detail=f"to {goal}")
        return fut

    @handler
    def on_stop_robot(self, msg: StopRobot) -> None:
        """Stop the robot's move and operation (its execution was abandoned)."""
        r = self.robots.get(msg.robot)
        if r is None:
            return
        if r.move is not None:
            self.world.stop(r.index)
            self._end_move(r, False, "stopped")
        self._abort(r, "stopped")

    def _end_move(self, r: _Robot, ok: bool, detail: str) -> None:
        fut, r.move = r.move, None
        cell = self.position(r.name)
        if r.move_event is not None:
            self._close(r.move_event, ok, detail)
            r.move_event = None
        if fut is not None and not fut.done():
            fut.set_result(SimResult(ok, cell, detail))
        self._tell_position(r)

    def _tell_position(self, r: _Robot, done: _Op | None = None) -> None:
        """Tell the robot's body where it is and what it is doing, or has ``done`` (see
        :class:`~btcap.sim.world.messages.PositionUpdate`)."""
        if self._system is None:
            return
        msg = PositionUpdate(r.name, self.position(r.name))
        op = r.busy[-1] if r.busy else done
        if op is not None:
            msg.op, msg.target = op.event.kind, op.target
            msg.phase = "done" if op is done else "work" if op.working else "carry"
        if self.on_position is not None:
            self.on_position(msg)
        else:
            self.system.ref(Address(r.name, "body")).tell(msg)

    @handler
    def on_operate(self, msg: Operate) -> SimResult | asyncio.Future[SimResult]:
        r = self._robot(msg.robot)
        if r is None:
            return self._refuse(msg.robot, "unknown or failed robot")
        if msg.op not in ("explore", "identify", "decontaminate") or not r.model.can(msg.op):
            return self._refuse(msg.robot, f"robot cannot {msg.op}")
        if msg.op != "explore" and not 0 <= msg.target < len(self.state.objects):
            return self._refuse(msg.robot, f"no object {msg.target}")
        if r.move is not None:  # one body: it works where it is, it does not drive on
            self.world.stop(r.index)
            self._end_move(r, False, "superseded")
        self._abort(r, "superseded")  # one operation at a time: a new request supersedes
        key = _key(msg.op, msg.target, self.position(r.name))
        factor, fails = self.draw(msg.op, msg.target, self.position(r.name))
        duration = r.model.operation(msg.op).duration_s * factor
        fut: asyncio.Future[SimResult] = asyncio.get_running_loop().create_future()
        op = _Op(fut, self._event(r.name, msg.op, target=msg.target), msg.target, key)
        op.working = msg.op != "decontaminate"  # which first carries the object
        r.busy.append(op)
        self._tell_position(r)
        self.start_task(self._operate(r, msg, duration, fails, op), name=f"{msg.op} {r.name}")
        return fut

    async def _operate(
        self, r: _Robot, msg: Operate, duration: float, fails: bool, op: _Op
    ) -> None:
        state = self.state
        clock = self.system.clock
        try:
            if msg.op == "decontaminate":
                obj = state.objects[msg.target]
                if obj.carried_by is not None or obj.decontaminated:
                    self._end_op(r, op, SimResult(False, self.position(r.name), "object taken"))
                    return
                state.pick_up(msg.target, r.name)
                r.carrying = msg.target
                op.carrying = True
                self.world.set_goal(r.index, state.grid.decon_area)
                while self.position(r.name) != state.grid.decon_area:
                    await clock.sleep(self.config.step_s)
                    if op.fut.done():  # superseded, stopped or the robot went down
                        return
                op.working = True
                self._tell_position(r)
            await clock.sleep(duration)
            if op.fut.done():
                return
            self._attempts[op.key] = self._attempts.get(op.key, 0) + 1  # ran to its end
            cell = self.position(r.name)
            if fails:
                self._end_op(r, op, SimResult(False, cell, "operation failed"))
                return
            result = SimResult(True, cell)
            if msg.op == "explore":
                result.found = state.explore(cell, r.model.operation("explore").radius_m)
            elif msg.op == "identify":
                result.contaminated = state.identify(msg.target)
            else:
                state.decontaminated(msg.target)
                r.carrying = -1
                op.carrying = False
            self._end_op(r, op, result)
        finally:
            if not op.fut.done():  # the manager is stopping
                self._end_op(r, op, SimResult(False, self.position(r.name), "interrupted"))

    def _abort(self, r: _Robot, why: str) -> None:
        """End the robot's operations unfinished; an object it carries falls where it is."""
        for op in list(r.busy):
            self._end_op(r, op, SimResult(False, self.position(r.name), why))

    def _end_op(self, r: _Robot, op: _Op, result: SimResult) -> None:
        if op in r.busy:
            r.busy.remove(op)
        if op.carrying:  # unfinished: the object stays where the robot is
            op.carrying = False
            if r.carrying == op.target:
                self.state.drop(op.target, result.position)
                r.carrying = -1
                if r.move is None and r.up:
                    self.world.stop(r.index)  # no longer bound for the decon area
        if not op.fut.done():
            op.fut.set_result(result)
        self._close(op.event, result.ok, result.detail)
        # No operation under way any more (and carrying moved the robot).
        self._tell_position(r, op if result.ok else None)

    # -- timeline ---------------------------------------------------------------------
    def _event(self, robot: str, kind: str, *, target: int = -1, detail: str = "") -> SimEvent:
        e = SimEvent(robot, kind, self.now(), target=target, detail=detail)
        self.events.append(e)
        return e

    def _close(self, e: SimEvent, ok: bool, detail: str) -> None:
        if e.end is None:
            e.end = self.now()
            e.ok = ok
            if detail:
                e.detail = detail

    def snapshot(self) -> dict[str, Any]:
        return {
            "time": self.now(),
            **self.state.summary(),
            "robots": {
                n: {"cell": self.position(n), "up": r.up, "carrying": r.carrying}
                for n, r in self.robots.items()
            },
        }
