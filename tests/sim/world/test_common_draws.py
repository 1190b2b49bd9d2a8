"""Common random numbers: an operation's random duration and failure, and the cells that
become exploration goals, depend on what the event is, not on what was drawn before it
(so runs of one seed that award the work differently compare the awards, not noise)."""

from __future__ import annotations

import asyncio

import numpy as np

from btcap.sim import GridMap
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.messages import MoveTo, Operate
from btcap.sim.world.store import MissionState
from tests.sim.world.test_manager import GRID, config, objects, simulation


def took(manager: SimulationManager, kind: str) -> dict[int, tuple[float, bool | None]]:
    """Per target: how long its (last) ``kind`` operation took and whether it succeeded."""
    return {
        e.target: (round(e.end - e.start, 6), e.ok)
        for e in manager.events
        if e.kind == kind and e.end is not None and e.detail != "superseded"
    }


async def identify_each(
    order: list[tuple[str, int]], seed: int
) -> dict[int, tuple[float, bool | None]]:
    """Identify the objects one after the other, by the robots given, with a wide jitter
    and failures; what each took."""
    async with simulation(config(delay_jitter=0.5, failure_chance=0.5, seed=seed)) as sim:
        for robot, target in order:
            await sim.run(sim.ask(Operate(robot, "identify", target)))
        return took(sim.manager, "identify")


async def test_an_operation_draws_the_same_whatever_ran_before_and_whoever_does_it() -> None:
    for seed in (1, 2, 3):
        forward = await identify_each([("r1", 0), ("r1", 1), ("r1", 2)], seed)
        backward = await identify_each([("r2", 2), ("r1", 1), ("r2", 0)], seed)
        assert forward == backward, seed
    # and the draws are random: durations and outcomes vary over objects and seeds
    runs = [await identify_each([("r1", 0), ("r1", 1), ("r1", 2)], s) for s in range(1, 7)]
    assert len({d for run in runs for d, _ in run.values()}) > 4
    assert {ok for run in runs for _, ok in run.values()} == {True, False}


async def test_an_attempt_cut_short_leaves_its_draw_to_the_next() -> None:
    cfg = config(delay_jitter=0.5, failure_chance=0.5, seed=4)
    m = SimulationManager(MissionState(GRID, objects()), cfg)
    first = m.draw("identify", 1, (0, 0))
    assert m.draw("identify", 1, (5, 5)) == first  # where the robot is: no matter
    async with simulation(cfg) as sim:
        cut = asyncio.ensure_future(sim.ask(Operate("r1", "identify", 1)))
        await sim.advance(1.0)
        await sim.run(sim.ask(MoveTo("r1", (1, 3))))  # driving off supersedes it
        assert (await cut).detail == "superseded"
        assert sim.manager.draw("identify", 1, (0, 0)) == first
        await sim.run(sim.ask(Operate("r1", "identify", 1)))
        # an attempt that ran to its end: the next one draws anew
        assert sim.manager.draw("identify", 1, (0, 0)) != first
    assert m.draw("explore", -1, (1, 2)) == m.draw("explore", 7, (1, 2))
    assert m.draw("explore", -1, (1, 2)) != m.draw("explore", -1, (1, 3))


def test_exploring_elsewhere_first_does_not_change_the_goals_here() -> None:
    grid = GridMap.from_array(np.ones((40, 40), dtype=bool), start=(20, 20), decon_area=(0, 0))

    def goals_near(cell: tuple[int, int], before: list[tuple[int, int]]) -> set[tuple[int, int]]:
        state = MissionState(grid, [], rng=np.random.default_rng(5))
        for c in before:
            state.explore(c, 3.0)
        state.explore(cell, 3.0)
        return {
            g.cell
            for g in state.pending_goals()
            if abs(g.cell[0] - cell[0]) <= 6 and abs(g.cell[1] - cell[1]) <= 6
        }

    here = goals_near((6, 6), [])
    assert len(here) >= 3
    assert goals_near((6, 6), [(33, 33)]) == here
    assert goals_near((6, 6), [(33, 6), (33, 33), (6, 33)]) == here
