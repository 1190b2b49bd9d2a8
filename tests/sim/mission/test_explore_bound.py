"""Exploration in the lower bound: when a cell can have been covered at the earliest.

Sans-IO: the bound's cover times against explorers walked through the store by hand.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from btcap.sim.mission.bound import (
    Presence,
    cover_times,
    mission_bound,
    scenario_bound,
    visit_tree_m,
)
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.world.distance import distance_field
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import OperationModel, RobotModel, paper_team
from btcap.sim.world.store import MissionState

PROBE = RobotModel(cost_factor=1.0, speed_mps=1.0, explore=OperationModel(1.0, 2.0))


def walled() -> GridMap:
    """9 x 20: a wall along row 4 from the left, open only at its two right columns."""
    free = np.ones((9, 20), dtype=bool)
    free[4, :18] = False
    return GridMap.from_array(free, start=(8, 0), decon_area=(8, 19))


def test_cover_times_price_the_path_round_a_wall_not_the_straight_line() -> None:
    grid = walled()
    cover = cover_times(grid, [PROBE])
    # (0, 0) is 8 m from the start in a straight line (6 m to within the 2 m radius),
    # but every cell within 2 m of it lies beyond the wall: 42 steps round its end
    assert cover[0, 0] == pytest.approx(42 + 1.0)
    assert cover[8, 5] == pytest.approx(3 + 1.0)  # in the open: drive to within 2 m
    # the mission ends no earlier than the last cell's cover (a straight flight: 19.6 s)
    assert mission_bound(grid, [PROBE], []).chains_s == pytest.approx(43.0)
    late = cover_times(grid, [PROBE], [Presence(start=10.0)], jitter=0.5)
    assert late[0, 0] == pytest.approx(10 + 42 + 0.5)


def walk(state: MissionState, model: RobotModel, order: str, rng: np.random.Generator) -> Any:
    """One explorer through the store's goals (at random, or the nearest first) until
    none is left; each cell's time of first cover."""
    grid, op = state.grid, model.operation("explore")
    first = np.full(grid.shape, np.inf)
    at, t = grid.start, 0.0
    while pending := state.pending_goals():
        steps = distance_field(grid.free, at)
        if order == "random":
            goal = pending[int(rng.integers(len(pending)))]
        else:
            goal = min(pending, key=lambda g: (steps[g.cell], g.id))
        t += steps[goal.cell] * grid.cell_size_m / model.speed_mps + op.duration_s
        at = goal.cell
        before = state.covered.copy()
        state.explore(at, op.radius_m)
        state.goal_done(goal.id)
        first[state.covered & ~before] = t
    return first


@pytest.mark.parametrize("kind", ["bebop", "husky"])
def test_no_explorer_covers_a_cell_before_its_cover_time(kind: str) -> None:
    grid = load_scenario(builtin_scenarios()["full-team"]).grid()
    model = paper_team()[kind]
    bound = cover_times(grid, [model])
    reach = grid.reachable
    for seed in range(6):
        for order in ("random", "nearest"):
            rng = np.random.default_rng(seed)
            state = MissionState(grid, [], rng=rng)
            first = walk(state, model, order, rng)
            assert np.isfinite(first[reach]).all()
            assert (first[reach] >= bound[reach] - 1e-9).all(), (seed, order)


def test_the_bound_is_no_lower_than_the_straight_line_one_on_the_caves() -> None:
    # the cover time by path is never below the straight flight it replaced
    grid = load_scenario(builtin_scenarios()["full-team"]).grid()
    bebop = paper_team()["bebop"]
    cover = cover_times(grid, [bebop])
    rows, cols = np.nonzero(grid.reachable)
    straight = np.hypot(rows - grid.start[0], cols - grid.start[1]) * grid.cell_size_m
    line = np.maximum(0.0, straight - 30.0) / bebop.speed_mps + 10.0
    assert (cover[rows, cols] >= line - 1e-9).all()
    assert (cover[rows, cols] > line + 5.0).any()  # and later where the cave winds
    s = load_scenario(builtin_scenarios()["full-team"])
    assert scenario_bound(s).chains_s >= float(cover[rows, cols].max()) - 10.0 * 0.2


def test_the_bound_counts_the_drives_to_identify_every_object() -> None:
    # A corridor, start and decontamination area at one end, two clean objects at 20 and
    # 40 m: one Husky must drive 40 m (1 m/s) besides its two 60 s identifications.
    grid = GridMap.from_array(np.ones((1, 41), dtype=bool), start=(0, 0), decon_area=(0, 0))
    husky = paper_team()["husky"]
    objects = [((0, 40), False), ((0, 20), False)]
    assert visit_tree_m(grid, [cell for cell, _ in objects]) == pytest.approx(40.0)
    b = mission_bound(grid, [husky], objects)
    # and explores twice: cells 0 and 31 m are more than a 15 m disc's diameter apart
    # (more than the 41 cells at the seconds per cell of such a disc: 3.5 s)
    assert b.work_s == pytest.approx(2 * 60 + 40 + 2 * 60, abs=0.1)
    # two robots may share the drives, never below a spanning tree: a cross of four arms
    # of 10 m, start in its middle, needs 40 m whoever drives them
    free = np.zeros((21, 21), dtype=bool)
    free[10, :] = free[:, 10] = True
    cross = GridMap.from_array(free, start=(10, 10), decon_area=(10, 10))
    assert visit_tree_m(cross, [(0, 10), (20, 10), (10, 0), (10, 20)]) == pytest.approx(40.0)
