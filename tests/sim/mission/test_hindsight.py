"""The schedule made in hindsight, against optima worked out by hand on tiny maps, and
never below the lower bound on the built-in scenarios.

Sans-IO: maps, models and the simulation's draws, no mission runs.
"""

from __future__ import annotations

import numpy as np
import pytest

from btcap.sim.mission.bound import Draws, Presence, mission_bound, scenario_bound
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.hindsight import hindsight_schedule, scenario_hindsight, walked_found
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.world.manager import SimConfig
from btcap.sim.world.model import OperationModel, RobotModel
from btcap.sim.world.store import MissionState
from tests.sim.mission.test_explore_bound import walk
from tests.sim.mission.test_mission_bound import CART, DRONE, corridor

#: Every operation takes its model's duration and none fails.
EXACT = SimConfig(delay_jitter=0.0, failure_chance=0.0, seed=1)


def draws() -> Draws:
    return Draws(MissionState(corridor(), [], rng=np.random.default_rng(0)), EXACT)


def test_one_cart_identifies_and_carries_as_worked_out_by_hand() -> None:
    # A corridor, start and decontamination area at its left end: a contaminated object
    # at 20 m, a clean one at 40 m. The cart (1 m/s, identify 10 s, carry 1 s) drives 20,
    # identifies (30), carries back (50) and decontaminates (51), drives 40 and
    # identifies: 101 s, and every other order is no sooner. The bound says as much.
    grid = corridor()
    objects = [((0, 20), True), ((0, 40), False)]
    present = [Presence(), Presence()]
    h = hindsight_schedule(grid, [DRONE, CART], objects, present, 0.0, draws())
    assert h.seconds == pytest.approx(101.0)
    assert h.busy_s[1] == pytest.approx(101.0)
    assert mission_bound(grid, [DRONE, CART], objects).seconds == pytest.approx(101.0)
    # out of the team for its first 50 s, it does it all after
    away = [Presence(), Presence(gaps=((0.0, 50.0),))]
    late = hindsight_schedule(grid, [DRONE, CART], objects, away, 0.0, draws())
    assert late.seconds == pytest.approx(151.0)
    assert mission_bound(grid, [DRONE, CART], objects, away).seconds == pytest.approx(151.0)


def test_a_walk_finds_objects_as_the_store_hands_out_goals() -> None:
    grid = corridor()
    objects = [((0, 20), True), ((0, 40), False)]
    found = walked_found(grid, [DRONE, CART], [Presence(), Presence()], objects, draws())
    assert found is not None
    state = MissionState(grid, [], rng=np.random.default_rng(0))
    first = walk(state, DRONE, "nearest", np.random.default_rng(0))
    assert found[0] == pytest.approx([first[0, 20], first[0, 40]])
    assert found[1] == pytest.approx(first[grid.reachable].max())
    # two explorers: one waits while the other's exploration may still add goals
    two = walked_found(grid, [DRONE, DRONE], [Presence(), Presence()], objects, draws())
    assert two is not None
    assert two[0][1] <= found[0][1]
    # the cart cannot only explore: no walk without a robot that does
    assert walked_found(grid, [CART], [Presence()], objects, draws()) is None


@pytest.mark.parametrize("seed", [1, 3])
def test_the_schedule_is_never_below_the_bound(seed: int) -> None:
    s = load_scenario(builtin_scenarios()["full-team"])
    s.seed = seed
    bound = scenario_bound(s).seconds
    assert scenario_hindsight(s, tries=3).seconds >= bound
    if seed == 3:  # the Husky alone carries: the bound is a schedule's end (466.7 s)
        assert scenario_hindsight(s).seconds == pytest.approx(bound, abs=0.1)


def test_no_schedule_where_the_object_workers_must_explore() -> None:
    # single-husky: the Husky explores too, which the schedule leaves out; it would end
    # 1976 s into seed 1, before the bound's 2663 s (exploring counted)
    s = load_scenario(builtin_scenarios()["single-husky"])
    assert scenario_hindsight(s, tries=1) is None


def test_a_slow_robot_takes_its_time() -> None:
    # Two carts, one four times slower: the schedule gives it nothing far
    slow = RobotModel(cost_factor=1.0, speed_mps=0.25, identify=OperationModel(10.0))
    grid = corridor()
    objects = [((0, 40), False)]
    present = [Presence()] * 3
    h = hindsight_schedule(grid, [DRONE, CART, slow], objects, present, 0.0, draws())
    assert h.seconds == pytest.approx(50.0)
    assert h.busy_s[2] == 0.0
