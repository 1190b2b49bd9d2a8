"""The world the ROS simulator hosts' tests build their hosts on."""

from __future__ import annotations

import numpy as np

from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import Scenario, load_scenario
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.store import MissionState


def world(name: str) -> tuple[Scenario, GridMap, SimulationManager]:
    """Built-in scenario ``name``, its map and a simulation manager of it (seed 1)."""
    s = load_scenario(builtin_scenarios()[name])
    grid = s.grid()
    state = MissionState.scatter(grid, s.objects, s.contaminated_share, np.random.default_rng(1))
    return s, grid, SimulationManager(state, SimConfig(s.sim.step_s, 0.0, 0.0, 1))
