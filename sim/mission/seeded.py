"""The world a scenario's seed makes, as the bound and the hindsight schedule read it:
the objects scattered as the runner scatters them, the operations on them drawn as every
run of the seed draws them, and who is present when."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from btcap.sim.mission.opdraws import Draws
from btcap.sim.mission.presence import Presence, presence
from btcap.sim.mission.scenario import Scenario
from btcap.sim.world.distance import Cell
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimConfig
from btcap.sim.world.model import RobotModel
from btcap.sim.world.store import MissionState

__all__ = ["SeededWorld", "seeded_world"]


@dataclass(frozen=True)
class SeededWorld:
    grid: GridMap
    robots: list[RobotModel]  # in the scenario's order of robots
    objects: list[tuple[Cell, bool]]  # (cell, contaminated)
    presence: list[Presence]
    jitter: float
    draws: Draws


def seeded_world(s: Scenario) -> SeededWorld:
    grid = s.grid()
    state = MissionState.scatter(
        grid, s.objects, s.contaminated_share, np.random.default_rng(s.seed)
    )
    models = s.models()
    config = SimConfig(s.sim.step_s, s.sim.delay_jitter, s.sim.failure_chance, s.seed)
    return SeededWorld(
        grid,
        [models[r.model] for r in s.robots],
        [(o.cell, o.contaminated) for o in state.objects],
        presence([r.name for r in s.robots], s.events),
        s.sim.delay_jitter,
        Draws(state, config),
    )
