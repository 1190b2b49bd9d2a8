"""Bids in time: a scenario's robots may bid seconds (the drive at the robot's speed plus
the work) instead of the paper's cost units (metres x cost factor plus the work), so
work goes to the robot that ends it first."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, cast

import anyio
import pytest

from btcap.sim.mission.capabilities import robot_setup
from btcap.sim.mission.scenario import ScenarioError, builtin_scenarios, load_scenario
from btcap.sim.running.runner import run_fast
from btcap.sim.world.distance import DistanceCache, path_length
from btcap.sim.world.grid import GridMap
from btcap.sim.world.messages import PositionUpdate
from btcap.sim.world.model import paper_team
from btcap.sim.world.robot import Body


def _bid(robot: str, model: str, grid: GridMap, interface: str, **kw: Any) -> Any:
    setup = robot_setup(robot, paper_team()[model], grid, **kw)
    impl = next(i for i in setup.implementations if i.interface.name == interface)
    body = setup.actors[Body.PATH]
    assert isinstance(body, Body)
    return impl.bid, body  # type: ignore[attr-defined]


def _far(grid: GridMap) -> tuple[int, int]:
    return max(
        ((r, c) for r in range(grid.height) for c in range(grid.width) if grid.is_free((r, c))),
        key=lambda cell: abs(cell[0] - grid.start[0]) + abs(cell[1] - grid.start[1]),
    )


def test_a_bebop_bids_the_seconds_its_flight_and_exploration_take() -> None:
    """The paper's unit prices a Bebop's metre as 1 (cost factor 1.0) though it flies
    3 m/s: in time its flight costs a third of that."""
    grid = GridMap.generate_cave(60, 40, seed=2)
    far = _far(grid)
    metres = path_length(DistanceCache(grid.free).get(far), grid.start, grid.cell_size_m)
    paper, _ = _bid("bebop1", "bebop", grid, "Explore")
    time, _ = _bid("bebop1", "bebop", grid, "Explore", bids="time")
    assert paper({"goal": far}) == pytest.approx(metres * 1.0 + 10.0)
    assert time({"goal": far}) == pytest.approx(metres / 3.0 + 10.0)


def test_a_huskys_carry_in_time_counts_both_drives_at_its_speed() -> None:
    grid = GridMap.generate_cave(60, 40, seed=2)
    far = _far(grid)
    cache = DistanceCache(grid.free)
    there = path_length(cache.get(far), grid.start, grid.cell_size_m)
    on = path_length(cache.get(grid.decon_area), far, grid.cell_size_m)
    time, body = _bid("husky1", "husky", grid, "MoveToDecontamination", bids="time")
    inputs = {"object": 3, "at": far}
    assert time(inputs) == pytest.approx(there / 1.0 + 8.0 + on / 1.0)
    # picked up: the drive on at its speed, then the work
    body.on_position(PositionUpdate("husky1", far, "decontaminate", 3, "carry"))
    assert time(inputs) == pytest.approx(on / 1.0 + 8.0)


def test_an_unknown_unit_is_refused() -> None:
    grid = GridMap.generate_cave(30, 20, seed=2)
    with pytest.raises(ValueError, match="bids: expected 'paper' or 'time'"):
        robot_setup("husky1", paper_team()["husky"], grid, bids="euros")  # type: ignore[arg-type]


def test_a_scenario_bids_the_papers_units_unless_it_says_time(tmp_path: Path) -> None:
    s = load_scenario(builtin_scenarios()["huskies-bebop-joins"])
    assert s.bids == "paper"
    text = builtin_scenarios()["huskies-bebop-joins"].read_text() + "bids: time\n"
    (tmp_path / "timed.yaml").write_text(text)
    assert load_scenario(tmp_path / "timed.yaml").bids == "time"
    (tmp_path / "bad.yaml").write_text(text.replace("bids: time", "bids: euros"))
    with pytest.raises(ScenarioError, match="bids"):
        load_scenario(tmp_path / "bad.yaml")


#: Wall seconds a fast mission may take on a loaded machine (a hang bound, not speed).
RUN_S = 300.0


@pytest.mark.slow
@pytest.mark.parametrize("bids", ["paper", "time"])
async def test_a_joining_bebop_takes_over_the_exploration_it_ends_sooner_in_time(
    bids: str,
) -> None:
    """The paper's Fig. 5 case of docs/mission.md, seed 1, the paper's tree: at the join
    the exploring Husky has 24 s left (24 cost units too), the Bebop needs 18.7 s but
    bids 36 cost units. In cost units the work stays and the Bebop waits; in seconds it
    moves (more than ``move_margin`` less) and the Husky's exploration is cut there."""
    s = load_scenario(builtin_scenarios()["huskies-bebop-joins"])
    s.seed, s.bids = 1, cast(Literal["paper", "time"], bids)
    with anyio.fail_after(RUN_S):
        result = await run_fast(s)
    assert result.completed
    joined = next(m.time for m in result.marks if m.event == "joined" and m.robot == "bebop1")
    husky = next(
        i
        for i in result.timeline
        if i.kind == "explore" and i.robot.startswith("husky") and i.start < joined <= i.end
    )
    bebop = [i for i in result.timeline if i.robot == "bebop1"]
    if bids == "paper":
        assert husky.ok  # it explored on to its end
        assert husky.end > joined + 10.0
        assert bebop[0].start > joined + 10.0  # the Bebop waited for other work
    else:
        assert not husky.ok  # cut: the work moved
        assert husky.end <= joined + 5.0
        assert bebop[0].start <= joined + 5.0
        assert result.moved >= 1


def test_the_missionbound_bench_bids_what_it_is_told() -> None:
    from btcap.bench.allocation.missionbound import scenario

    assert scenario("huskies-bebop-joins", 3, "pool").bids == "paper"
    assert scenario("full-team-6", 3, "pool", "time").bids == "time"
