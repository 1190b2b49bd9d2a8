"""The simulation manager: moves and operations answered after clock time, failures,
robots going down, refusals and superseded requests (on a manual clock)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Awaitable
from contextlib import asynccontextmanager
from dataclasses import dataclass
from typing import Any

import anyio
import numpy as np
import pytest

from btcap.actors import ActorRef, ActorSystem, ManualClock
from btcap.sim import GridMap
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.messages import MoveTo, Operate, SimResult, StopRobot
from btcap.sim.world.model import OperationModel, RobotModel
from btcap.sim.world.robot import Body
from btcap.sim.world.store import MissionState, SimObject

# A 3 x 40 corridor, robots start at the left end, decontamination at the right end.
GRID = GridMap.from_array(np.ones((3, 40), dtype=bool), start=(1, 0), decon_area=(1, 39))
WALLED = GridMap.from_array(
    np.array([[1, 1, 1, 0, 1], [1, 1, 1, 0, 1], [1, 1, 1, 1, 1]], dtype=bool),
    start=(0, 0),
    decon_area=(2, 4),
)

WORKER = RobotModel(
    cost_factor=1.0,
    speed_mps=2.0,
    explore=OperationModel(10.0, 3.0),
    identify=OperationModel(4.0),
    decontaminate=OperationModel(2.0),
)
LOOKER = RobotModel(cost_factor=1.0, speed_mps=1.0, identify=OperationModel(1.0))
STEP = 0.5


@dataclass
class Sim:
    clock: ManualClock
    system: ActorSystem
    manager: SimulationManager
    ref: ActorRef[SimulationManager]
    state: MissionState
    body: Body

    async def run(self, request: Awaitable[Any], limit_s: float = 2000.0) -> SimResult:
        """Advance the clock until ``request`` is answered."""
        task: asyncio.Future[Any] = asyncio.ensure_future(request)
        for _ in range(3):  # let the request reach the manager before time moves
            await asyncio.sleep(0)
        waited = 0.0
        while not task.done():
            assert waited <= limit_s, "no answer in time"
            await self.clock.advance(STEP)
            waited += STEP
        result = task.result()
        assert isinstance(result, SimResult)
        return result

    def ask(self, msg: Any) -> Awaitable[Any]:
        return self.ref.ask(msg, expect=SimResult, timeout=3600.0)  # clock seconds

    async def advance(self, seconds: float) -> None:
        for _ in range(round(seconds / STEP)):
            await self.clock.advance(STEP)

    def obj(self, i: int) -> SimObject:
        return self.state.objects[i]


def objects() -> list[SimObject]:
    # 0 and 2 contaminated, 1 clean; all found.
    return [
        SimObject(0, (1, 10), True, found=True),
        SimObject(1, (0, 12), False, found=True),
        SimObject(2, (2, 20), True, found=True),
    ]


def config(**kw: Any) -> SimConfig:
    return SimConfig(**{"step_s": STEP, "delay_jitter": 0.0, "failure_chance": 0.0, **kw})


@asynccontextmanager
async def simulation(cfg: SimConfig | None = None) -> AsyncIterator[Sim]:
    clock = ManualClock()
    state = MissionState(GRID, objects())
    manager = SimulationManager(state, cfg or config())
    manager.add_robot("r1", WORKER)
    manager.add_robot("r2", WORKER)
    manager.add_robot("spot", LOOKER, (0, 5))
    with anyio.fail_after(20):
        # The system is named r1, so the manager's position updates reach r1's body.
        async with ActorSystem("r1", clock=clock) as system:
            body = Body("r1", GRID.start)
            system.spawn(body, Body.PATH)
            ref = system.spawn(manager, SimulationManager.PATH)
            yield Sim(clock, system, manager, ref, state, body)


def events(manager: SimulationManager, robot: str) -> list[tuple[str, bool | None, str]]:
    return [(e.kind, e.ok, e.detail) for e in manager.events if e.robot == robot]


# -- moves ----------------------------------------------------------------------------------


async def test_move_answers_on_arrival() -> None:
    async with simulation() as sim:
        result = await sim.run(sim.ask(MoveTo("r1", (1, 20))))
        assert (result.ok, result.position, result.detail) == (True, (1, 20), "arrived")
        # 20 cells at 2 m/s: about 10 s of clock time, in whole steps.
        assert 10.0 <= sim.clock.now() <= 10.0 + 2 * STEP
        assert sim.manager.position("r1") == (1, 20)
        assert sim.body.position == (1, 20)
        (move,) = [e for e in sim.manager.events if e.kind == "move"]
        assert (move.robot, move.ok, move.start) == ("r1", True, 0.0)
        assert move.end == pytest.approx(sim.clock.now(), abs=STEP)
        assert sim.manager.world.travelled_m[0] == pytest.approx(20.0)


async def test_move_to_where_the_robot_is() -> None:
    async with simulation() as sim:
        result = await sim.ask(MoveTo("r1", GRID.start))
        assert (result.ok, result.detail) == (True, "already there")


async def test_move_to_a_wall_or_off_the_map_fails_at_once() -> None:
    async with simulation() as sim:
        for goal in ((5, 5), (-1, 0), (1, 400)):
            result = await sim.ask(MoveTo("r1", goal))
            assert not result.ok
            assert "not a free cell" in result.detail
        assert sim.clock.now() == 0.0


async def test_stop_ends_the_move_where_the_robot_is() -> None:
    async with simulation() as sim:
        task = asyncio.ensure_future(sim.ask(MoveTo("r1", (1, 30))))
        await sim.advance(3.0)
        sim.ref.tell(StopRobot("r1"))
        result = await sim.run(task)
        assert (result.ok, result.detail) == (False, "stopped")
        assert 0 < result.position[1] < 30
        await sim.advance(5.0)
        assert sim.manager.position("r1") == result.position  # it stays stopped
        assert sim.body.position == result.position
        sim.ref.tell(StopRobot("r1"))  # nothing to stop: harmless
        sim.ref.tell(StopRobot("nobody"))


async def test_a_new_move_supersedes_the_old_one() -> None:
    async with simulation() as sim:
        first = asyncio.ensure_future(sim.ask(MoveTo("r1", (1, 30))))
        await sim.advance(2.0)
        second = await sim.run(sim.ask(MoveTo("r1", (0, 2))))
        old = await sim.run(first)
        assert (old.ok, old.detail) == (False, "superseded")
        assert (second.ok, second.position) == (True, (0, 2))


async def test_robots_move_independently() -> None:
    async with simulation() as sim:
        a = asyncio.ensure_future(sim.ask(MoveTo("r1", (1, 8))))
        b = asyncio.ensure_future(sim.ask(MoveTo("r2", (2, 30))))
        ra = await sim.run(a)
        t_a = sim.clock.now()
        rb = await sim.run(b)
        assert ra.ok
        assert rb.ok
        assert t_a < sim.clock.now()


# -- operations -----------------------------------------------------------------------------


async def test_explore_takes_its_duration_and_reveals() -> None:
    async with simulation() as sim:
        sim.state.objects[0].found = False
        await sim.run(sim.ask(MoveTo("r1", (1, 9))))
        t0 = sim.clock.now()
        result = await sim.run(sim.ask(Operate("r1", "explore")))
        assert result.ok
        assert result.found == 1
        assert sim.obj(0).found
        assert sim.clock.now() - t0 == pytest.approx(10.0, abs=STEP)
        assert sim.state.coverage > 0
        (op,) = [e for e in sim.manager.events if e.kind == "explore"]
        assert op.ok
        assert op.end is not None
        assert op.end - op.start == pytest.approx(10.0)


async def test_identify_reports_the_ground_truth() -> None:
    async with simulation() as sim:
        dirty = await sim.run(sim.ask(Operate("spot", "identify", 0)))
        clean = await sim.run(sim.ask(Operate("spot", "identify", 1)))
        assert dirty.ok
        assert dirty.contaminated is True
        assert clean.ok
        assert clean.contaminated is False
        assert sim.obj(0).identified is True
        assert sim.obj(1).identified is False
        assert sim.obj(1).finished


async def test_decontaminate_carries_the_object_to_the_area() -> None:
    async with simulation() as sim:
        await sim.run(sim.ask(MoveTo("r1", sim.obj(2).cell)))
        task = asyncio.ensure_future(sim.ask(Operate("r1", "decontaminate", 2)))
        await sim.advance(2.0)
        assert sim.obj(2).carried_by == "r1"
        assert sim.manager.snapshot()["robots"]["r1"]["carrying"] == 2
        result = await sim.run(task)
        assert result.ok
        assert result.position == GRID.decon_area
        assert sim.body.position == GRID.decon_area  # carrying moved it
        o = sim.obj(2)
        assert o.decontaminated
        assert o.carried_by is None
        assert o.cell == GRID.decon_area
        assert sim.manager.robots["r1"].carrying == -1


async def test_decontaminating_a_taken_object_fails() -> None:
    async with simulation() as sim:
        sim.state.pick_up(0, "r2")
        result = await sim.run(sim.ask(Operate("r1", "decontaminate", 0)))
        assert (result.ok, result.detail) == (False, "object taken")
        assert sim.obj(0).carried_by == "r2"


async def test_jitter_randomises_durations_by_seed() -> None:
    def durations(seed: int) -> list[float]:
        m = SimulationManager(MissionState(GRID, objects()), config(delay_jitter=0.5, seed=seed))
        return [m.draw("identify", i, (0, 0))[0] for i in range(5)]

    assert durations(1) == durations(1)
    assert durations(1) != durations(2)


async def test_jittered_durations_stay_within_bounds() -> None:
    async with simulation(config(delay_jitter=0.5, seed=3)) as sim:
        for _ in range(4):
            t0 = sim.clock.now()
            result = await sim.run(sim.ask(Operate("r1", "identify", 0)))
            assert result.ok
            assert 2.0 - STEP <= sim.clock.now() - t0 <= 6.0 + STEP


async def test_operations_fail_with_the_failure_chance() -> None:
    async with simulation(config(failure_chance=1.0)) as sim:
        t0 = sim.clock.now()
        result = await sim.run(sim.ask(Operate("r1", "identify", 0)))
        assert (result.ok, result.detail) == (False, "operation failed")
        assert sim.clock.now() - t0 >= 4.0  # the failure comes after the duration
        assert sim.obj(0).identified is None
        explored = await sim.run(sim.ask(Operate("r1", "explore")))
        assert not explored.ok
        assert sim.state.coverage == 0.0
        # A failed decontamination drops the object where the robot is.
        result = await sim.run(sim.ask(Operate("r1", "decontaminate", 0)))
        assert not result.ok
        o = sim.obj(0)
        assert o.carried_by is None
        assert not o.decontaminated
        assert o.cell == GRID.decon_area == result.position
        assert sim.manager.robots["r1"].carrying == -1
        assert [ok for kind, ok, _ in events(sim.manager, "r1") if kind != "move"] == [False] * 3


# -- refusals -------------------------------------------------------------------------------


async def test_operations_the_robot_cannot_do_are_refused() -> None:
    async with simulation() as sim:
        for op in ("explore", "decontaminate", "teleport"):
            result = await sim.ask(Operate("spot", op, 0))
            assert (result.ok, result.detail) == (False, f"robot cannot {op}")
        result = await sim.ask(Operate("r1", "identify", 99))
        assert (result.ok, result.detail) == (False, "no object 99")
        result = await sim.ask(Operate("r1", "identify"))
        assert not result.ok
        assert not sim.manager.events


async def test_unknown_robot_is_refused() -> None:
    async with simulation() as sim:
        for msg in (MoveTo("ghost", (1, 2)), Operate("ghost", "identify", 0)):
            result = await sim.ask(msg)
            assert (result.ok, result.detail) == (False, "unknown or failed robot")


def test_robot_names_are_unique() -> None:
    m = SimulationManager(MissionState(GRID, objects()))
    m.add_robot("a", WORKER)
    with pytest.raises(ValueError, match="already"):
        m.add_robot("a", LOOKER)


# -- superseding and failures ---------------------------------------------------------------


async def test_a_new_operation_supersedes_the_previous_one() -> None:
    async with simulation() as sim:
        first = asyncio.ensure_future(sim.ask(Operate("r1", "explore")))
        await sim.advance(2.0)
        second = await sim.run(sim.ask(Operate("r1", "identify", 0)))
        old = await sim.run(first)
        assert (old.ok, old.detail) == (False, "superseded")
        assert second.ok
        await sim.advance(20.0)  # the superseded explore never takes effect
        assert sim.state.coverage == 0.0
        assert [(k, ok) for k, ok, _ in events(sim.manager, "r1")] == [
            ("explore", False),
            ("identify", True),
        ]


async def test_an_operation_ends_the_move() -> None:
    async with simulation() as sim:
        move = asyncio.ensure_future(sim.ask(MoveTo("r1", (1, 30))))
        await sim.advance(3.0)
        op = await sim.run(sim.ask(Operate("r1", "identify", 0)))
        old = await sim.run(move)
        assert (old.ok, old.detail) == (False, "superseded")
        assert op.ok
        assert op.position == old.position == sim.manager.position("r1")
        await sim.advance(5.0)
        assert sim.manager.position("r1") == old.position  # it did not drive on


async def test_a_move_supersedes_an_operation() -> None:
    async with simulation() as sim:
        op = asyncio.ensure_future(sim.ask(Operate("r1", "explore")))
        await sim.advance(2.0)
        move = await sim.run(sim.ask(MoveTo("r1", (1, 5))))
        assert move.ok
        old = await sim.run(op)
        assert (old.ok, old.detail) == (False, "superseded")
        await sim.advance(20.0)
        assert sim.state.coverage == 0.0


async def test_a_superseded_decontamination_drops_its_object() -> None:
    async with simulation() as sim:
        await sim.run(sim.ask(MoveTo("r1", sim.obj(0).cell)))
        first = asyncio.ensure_future(sim.ask(Operate("r1", "decontaminate", 0)))
        await sim.advance(3.0)
        assert sim.obj(0).carried_by == "r1"
        second = asyncio.ensure_future(sim.ask(Operate("r1", "decontaminate", 2)))
        old = await sim.run(first)
        assert (old.ok, old.detail) == (False, "superseded")
        await sim.advance(STEP * 2)
        o = sim.obj(0)
        assert o.carried_by is None, "the first object is lost"
        assert not o.decontaminated
        assert sim.state.claim("w", "object").status == "ok"
        result = await sim.run(second)
        assert result.ok
        assert sim.obj(2).decontaminated
        assert sim.obj(0).carried_by is None
        assert not sim.obj(0).decontaminated


async def test_stop_aborts_an_operation_and_drops_the_object() -> None:
    async with simulation() as sim:
        await sim.run(sim.ask(MoveTo("r1", sim.obj(0).cell)))
        task = asyncio.ensure_future(sim.ask(Operate("r1", "decontaminate", 0)))
        await sim.advance(3.0)
        sim.ref.tell(StopRobot("r1"))
        result = await sim.run(task)
        assert (result.ok, result.detail) == (False, "stopped")
        await sim.advance(STEP * 2)
        o = sim.obj(0)
        assert o.carried_by is None
        assert not o.decontaminated
        assert o.cell == result.position != GRID.decon_area
        assert sim.manager.position("r1") == result.position
        assert sim.manager.robots["r1"].carrying == -1


async def test_robot_down_fails_its_requests_and_drops_what_it_carries() -> None:
    async with simulation() as sim:
        move = asyncio.ensure_future(sim.ask(MoveTo("r2", (0, 30))))
        await sim.run(sim.ask(MoveTo("r1", sim.obj(0).cell)))
        carry = asyncio.ensure_future(sim.ask(Operate("r1", "decontaminate", 0)))
        await sim.advance(3.0)
        where = sim.manager.position("r1")
        sim.manager.robot_down("r1")
        sim.manager.robot_down("r2")
        assert (await sim.run(carry)).detail == "robot down"
        assert (await sim.run(move)).detail == "robot down"
        o = sim.obj(0)
        assert o.carried_by is None
        assert o.cell == where
        assert not o.decontaminated
        await sim.advance(5.0)
        assert sim.manager.position("r1") == where  # a failed robot does not move
        refused = await sim.ask(MoveTo("r1", (1, 1)))
        assert (refused.ok, refused.detail) == (False, "unknown or failed robot")
        refused = await sim.ask(Operate("r1", "identify", 1))
        assert not refused.ok
        snap = sim.manager.snapshot()
        assert snap["robots"]["r1"] == {"cell": where, "up": False, "carrying": -1}
        # Back up: it works again, from where it stopped.
        sim.manager.robot_up("r1")
        result = await sim.run(sim.ask(Operate("r1", "decontaminate", 0)))
        assert result.ok
        assert sim.obj(0).decontaminated


async def test_robot_down_during_an_operation_fails_it() -> None:
    async with simulation() as sim:
        task = asyncio.ensure_future(sim.ask(Operate("r1", "explore")))
        await sim.advance(2.0)
        sim.manager.robot_down("r1")
        result = await sim.run(task)
        assert (result.ok, result.detail) == (False, "robot down")
        sim.manager.robot_up("r1")
        await sim.advance(20.0)
        assert sim.state.coverage == 0.0
        (explore,) = [e for e in sim.manager.events if e.kind == "explore"]
        assert explore.ok is False
        assert explore.end is not None


async def test_walls_make_moves_take_the_long_way() -> None:
    clock = ManualClock()
    manager = SimulationManager(MissionState(WALLED, []), config())
    manager.add_robot("w", RobotModel(cost_factor=1.0, speed_mps=1.0))
    with anyio.fail_after(10):
        async with ActorSystem("walled", clock=clock) as system:
            ref = system.spawn(manager, "manager")
            task = asyncio.ensure_future(ref.ask(MoveTo("w", (0, 4)), timeout=3600.0))
            while not task.done():
                await clock.advance(STEP)
            assert task.result().ok
            assert clock.now() >= 8.0  # 8 cells around the wall, not 4 across it
