"""The pool mission (``mission: pool``) and the lower bound on mission time.

Whole missions on the virtual clock: deterministic, bounded by ``fail_after`` only to
catch a hang.
"""

from __future__ import annotations

from pathlib import Path

import anyio
import msgspec
import numpy as np
import pytest

import btcap.cli
import btcap.sim.running.runner
from btcap import Leaf, State, Tree
from btcap.cli import main
from btcap.sim.mission.bound import Presence, mission_bound, presence, scenario_bound
from btcap.sim.mission.pool import (
    SpareLane,
    StandByLane,
    pool_lanes,
    spare_explorers,
    standby_lanes,
)
from btcap.sim.mission.scenario import Event, Scenario, builtin_scenarios, load_scenario
from btcap.sim.running.metrics import Interval
from btcap.sim.running.runner import run_fast
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import paper_team
from btcap.sim.world.store import MissionState

pytestmark = pytest.mark.slow  # whole missions (the suite's bound for them: conftest)

RUN_S = 300.0
SMALL = Path(__file__).parents[1] / "data" / "small.yaml"


def scenario(name: str, seed: int, mission: str = "pool") -> Scenario:
    s = msgspec.structs.replace(load_scenario(builtin_scenarios()[name]), seed=seed)
    s.mission = mission
    return s


async def test_the_pool_mission_completes_and_the_bound_holds() -> None:
    s = scenario("full-team", 1)
    with anyio.fail_after(RUN_S):
        result = await run_fast(s)
    assert result.completed
    assert result.summary["decontaminated"] == result.summary["contaminated"] > 0
    bound = scenario_bound(s)
    assert 0 < bound.seconds <= result.mission_time_s
    # the pool runs one lane per robot able to do only this work: Bebop explores,
    # Spot identifies, and the Husky (alone able to carry) only carries
    tasks = {name: set(st.tasks) for name, st in result.robots.items()}
    assert tasks == {"husky1": {"decontaminate"}, "spot1": {"identify"}, "bebop1": {"explore"}}


async def test_an_object_dropped_by_a_failing_robot_keeps_its_one_lane(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Seed 1 with two explore lanes: husky2 fails while carrying object 8, which falls
    # where husky2 stood. Told apart by (id, cell), the dropped object was a new item: a
    # second lane carried it while the first (re-assigned) was refused again and again,
    # and once the list was complete (kept as it was then) the old item was offered for
    # ever: the mission hit its time limit. By id, the first lane is told the new cell.
    monkeypatch.setattr(btcap.sim.running.runner, "pool_lanes", lambda models: (2, 1, 2))
    s = scenario("huskies-bebop-joins", 1)
    s.time_limit_s = 2500.0
    with anyio.fail_after(RUN_S):
        result = await run_fast(s)
    assert result.completed, result.mission_time_s
    refused = [i for i in result.timeline if i.kind == "decontaminate" and i.start == i.end]
    assert len(refused) < 5


def test_lanes_go_to_robots_that_can_do_nothing_scarcer() -> None:
    team = paper_team()
    h, sp, b = team["husky"], team["spot"], team["bebop"]
    assert pool_lanes([h, sp, b]) == (1, 1, 1)
    assert pool_lanes([h, sp, b, h, sp, b]) == (2, 2, 2)
    assert pool_lanes([h]) == (1, 1, 1)
    assert pool_lanes([h, h, b]) == (1, 2, 2)  # no Spot: both Huskies identify


def test_the_bound_counts_the_carries_the_huskies_must_drive() -> None:
    # A corridor: start at one end, decontamination area at the other, objects between.
    free = np.ones((1, 41), dtype=bool)
    grid = GridMap.from_array(free, start=(0, 0), decon_area=(0, 40))
    team = paper_team()
    objects = [((0, 10), True), ((0, 20), True), ((0, 30), False)]
    b = mission_bound(grid, [team["husky"], team["spot"], team["bebop"]], objects)
    # carries: 10 -> 40 and 40 -> 20 -> 40 at 1 m/s (the first from the start: 10 m
    # there, 30 back) + 8 s each: 30 + 8 + 40 + 8 = 86 s, and 10 m before the first
    assert b.work_s == pytest.approx(2 * 30 + 2 * 20 + 16 - 20, abs=0.5)
    assert b.seconds >= b.work_s
    # a Husky present only from 100 s does all of it after
    late = mission_bound(
        grid,
        [team["husky"], team["spot"], team["bebop"]],
        objects,
        [Presence(start=100.0), Presence(), Presence()],
    )
    assert late.seconds >= 100.0 + 96.0


def test_presence_follows_joins_leaves_and_failures() -> None:
    events = [
        Event(at=120, robot="b", kind="join"),
        Event(at=700, robot="b", kind="leave"),
        Event(at=660, robot="h", kind="fail", duration=300),
    ]
    h, b = presence(["h", "b"], events)
    assert h.within(0, 1000) == pytest.approx(700)
    assert b.within(0, 1000) == pytest.approx(580)


def test_the_bound_is_below_every_paper_mission_run() -> None:
    # the paper's tree on its three scenarios, seed 1: figures from docs/mission.md
    for name, seconds in (("full-team", 1326.0), ("huskies-bebop-joins", 1402.5)):
        s = scenario(name, 1, "paper")
        assert scenario_bound(s).seconds <= seconds
    state = MissionState.scatter(scenario("full-team", 1).grid(), 10, 0.5, np.random.default_rng(1))
    assert sum(o.contaminated for o in state.objects) == 7


def test_btcap_run_takes_the_mission_and_prints_the_bound_beside_the_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)
    argv = ["run", str(SMALL), "--fast", "--mission", "pool", "--no-record", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 0
    line = capsys.readouterr().out.replace("\n", " ")
    assert "small: 3 robots, pool mission," in line
    assert "s of mission (lower bound " in line


async def test_a_carry_that_failed_runs_again_from_where_its_object_fell() -> None:
    # A carry fails at its end, in the decontamination area, and drops the object there.
    # Run again from the list read in the tick of the failure, the lane drove back to
    # where the object had been taken and carried it the whole way again (here: two
    # re-carries of 116 and 93 s; full-team-6 seed 5 lost 170 s so); from a list read
    # after the drop it is 8 s of work where the object lies.
    retried: list[Interval] = []
    for seed in range(1, 9):  # the first seed where a carry fails after carrying
        s = scenario("full-team", seed)
        # many operations fail: some carries surely do
        s.sim = msgspec.structs.replace(s.sim, failure_chance=0.3)
        with anyio.fail_after(RUN_S):
            result = await run_fast(s)
        assert result.completed
        carries = sorted(
            (i for i in result.timeline if i.kind == "decontaminate"), key=lambda i: i.start
        )
        retried = [
            next(b for b in carries if b.target == a.target and b.start >= a.end)
            for a in carries
            if not a.ok and a.end - a.start > 20  # failed at its end, after carrying
        ]
        if retried:
            break
    assert retried, "no carry failed after carrying on seeds 1-8"
    assert all(b.end - b.start < 8 * 1.2 + 2 for b in retried), [(b.start, b.end) for b in retried]


def test_carriers_with_no_other_lane_stand_by() -> None:
    team = paper_team()
    h, sp, b = team["husky"], team["spot"], team["bebop"]
    assert standby_lanes([h, sp, b]) == 1  # the Husky only carries: it stands by
    assert standby_lanes([h, sp, b, h, sp, b]) == 2
    assert standby_lanes([h, h, b]) == 0  # the Huskies identify: work, not waiting
    assert standby_lanes([h]) == 0


async def test_a_husky_stands_by_near_objects_before_any_is_found_contaminated() -> None:
    # Seed 3: the first contaminated object is identified at 331 s. The Husky used to
    # wait at the start until then and drive 134 s to it; it now follows the Spot to
    # the objects awaiting identification and is there sooner.
    s = scenario("full-team", 3)
    with anyio.fail_after(RUN_S):
        result = await run_fast(s)
    assert result.completed
    drives = [i for i in result.timeline if i.robot == "husky1" and i.kind == "move"]
    assert drives[0].start < 60.0  # out long before any object is known contaminated
    carry = min((i for i in result.timeline if i.kind == "decontaminate"), key=lambda i: i.start)
    found_dirty = next(
        j.end for j in result.timeline if j.kind == "identify" and j.target == carry.target
    )
    assert carry.start - found_dirty < 60.0  # was 135 s from the start
    assert result.mission_time_s < 760.0  # was 802 s


class Runs(Leaf):
    """RUNNING for ever; counts its ticks and resets."""

    def __init__(self) -> None:
        super().__init__("runs")
        self.ticks = self.resets = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return State.RUNNING

    def on_reset(self) -> None:
        self.resets += 1


def test_a_standby_lane_ends_once_its_object_is_identified_or_a_carry_waits() -> None:
    for listed, carries, ends in (
        ([(4, 1, 2)], [], False),  # awaiting identification, nothing to carry: drive on
        ([(5, 1, 2)], [], True),  # object 4 identified: no longer worth it
        ([(4, 1, 2)], [(6, 3, 3)], True),  # a carry waits: the robot is wanted there
    ):
        child = Runs()
        lane = StandByLane("lane", children=[child])
        tree = Tree(lane)
        lane.set_input("item", (4, 1, 2))
        lane.set_input("listed", [(4, 1, 2)])
        lane.set_input("carries", [])
        assert tree.tick() is State.RUNNING
        lane.set_input("listed", listed)
        lane.set_input("carries", carries)
        assert tree.tick() is (State.SUCCEEDED if ends else State.RUNNING)
        assert (child.ticks, child.resets > 0) == ((1, True) if ends else (2, False))


def test_robots_with_nothing_to_do_explore_while_no_object_waits() -> None:
    team = paper_team()
    h, sp, b = team["husky"], team["spot"], team["bebop"]
    assert spare_explorers([h, sp, b]) == 1  # the Husky, beside the Bebop's own lane
    assert spare_explorers([h, h, b]) == 2  # both Huskies before the Bebop joins
    assert spare_explorers([h]) == 0
    for identify, carry, runs in (
        ([], [], True),
        ([(1, 2, 3)], [], False),
        ([], [(1, 2, 3)], False),
    ):
        child = Runs()
        lane = SpareLane("lane", children=[child])
        tree = Tree(lane)
        lane.set_input("item", (0, 5, 5))
        lane.set_input("identify", [])
        lane.set_input("carry", [])
        assert tree.tick() is State.RUNNING
        lane.set_input("identify", identify)
        lane.set_input("carry", carry)
        # work waits: the exploration stops (the robot is freed) and the goal goes back
        assert tree.tick() is (State.RUNNING if runs else State.FAILED)
        assert child.resets == (0 if runs else 1)
