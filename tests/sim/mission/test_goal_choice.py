"""Which exploration goal the pool mission's explore lanes take next (GoalPool)."""

from __future__ import annotations

from pathlib import Path

import anyio
import numpy as np
import pytest

from btcap import Leaf, State, Tree
from btcap.sim.mission.goals import GoalPool
from btcap.sim.mission.pool import WorkLane
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast
from btcap.sim.world.grid import GridMap

RUN_S = 300.0


def corridor(length: int, height: int = 3) -> GridMap:
    """A straight corridor ``length`` cells long, the start in its middle."""
    free = np.zeros((height + 2, length + 2), dtype=bool)
    free[1:-1, 1:-1] = True
    mid = (height + 2) // 2
    return GridMap.from_array(free, start=(mid, length // 2 + 1), decon_area=(mid, 1))


class Explores(Leaf):
    """Stands in for Explore: RUNNING in the tick it starts, SUCCEEDED in the next."""

    def __init__(self) -> None:
        super().__init__("explore")
        self.ticks = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return State.SUCCEEDED if self.ticks % 2 == 0 else State.RUNNING

    def on_reset(self) -> None:
        self.ticks = 0


def goal_of(lane: WorkLane) -> int:
    return int(lane.inputs["item"][0]) if lane.state is State.RUNNING else -1


def test_a_free_lane_takes_the_goal_nearest_to_where_it_left_its_explorer() -> None:
    grid = corridor(60)  # start at column 31
    lane = WorkLane("goal_1", children=[Explores()])
    pool = GoalPool("each_goal", children=[lane], key=0, grid=grid)
    tree = Tree(pool)
    west, east, far_west = (1, 2, 26), (2, 2, 56), (3, 2, 6)
    pool.set_input("items", [west, east, far_west])  # oldest first, as the store lists
    pool.set_input("complete", False)
    pool.set_input("listed_at", tree.clock.now())
    tree.tick()
    assert goal_of(lane) == 1  # 5 cells from the start
    tree.tick()  # goal 1 explored (column 26): the lane is free
    assert goal_of(lane) == -1  # waits for a list asked for after that
    pool.set_input("items", [east, far_west])
    pool.set_input("listed_at", tree.clock.now() + 1.0)
    tree.tick()
    # oldest first took goal 2 (30 cells east), then flew back past the start to goal 3
    assert goal_of(lane) == 3  # 20 cells on, to the west


def test_goals_near_one_another_lane_explores_come_last() -> None:
    grid = corridor(60)
    lanes = [WorkLane(f"goal_{k}", children=[Explores()]) for k in (1, 2)]
    pool = GoalPool("each_goal", children=lanes, key=0, grid=grid, near_m=10.0)
    tree = Tree(pool)
    pool.set_input("items", [(1, 2, 30), (2, 2, 33), (3, 2, 50)])
    pool.set_input("complete", False)
    tree.tick()
    # lane 1 takes goal 1 beside the start; goal 2 is 3 m from it (its exploration may
    # cover it): lane 2 takes goal 3, though farther
    assert [goal_of(lane) for lane in lanes] == [1, 3]


@pytest.mark.slow
async def test_an_explorer_in_a_corridor_explores_one_side_then_the_other(
    tmp_path: Path,
) -> None:
    # A Bebop alone explores a corridor 240 m long from its middle (30 m radius): goals
    # come in pairs, one on each side. Taken oldest first it flew from side to side, ever
    # farther (286.5 s to explore it all when this was written); taking the goal nearest
    # to where it is, it does one side, then flies back once for the other (170.5 s).
    grid = corridor(240)
    grid.save(tmp_path / "corridor.txt")
    (tmp_path / "corridor.yaml").write_text(
        "name: corridor\n"
        "description: A straight corridor, the start in its middle.\n"
        "seed: 1\n"
        "objects: 0\n"
        "mission: pool\n"
        "time_limit_s: 3000\n"
        "map: {file: corridor.txt}\n"
        "sim: {step_s: 0.5, delay_jitter: 0.0, failure_chance: 0.0}\n"
        "robots:\n"
        "  - {name: bebop1, model: bebop}\n",
        encoding="utf-8",
    )
    s = load_scenario(tmp_path / "corridor.yaml")
    with anyio.fail_after(RUN_S):
        result = await run_fast(s)
    assert result.completed
    assert result.summary["coverage"] == 1.0
    explored = [i for i in result.timeline if i.kind == "explore" and i.ok]
    flown = sum(i.end - i.start for i in result.timeline if i.kind == "move")
    # the least flight: 90 m west in three legs, 210 m back east in three: 100 s at 3 m/s
    assert flown < 120.0, flown
    assert max(i.end for i in explored) < 200.0
