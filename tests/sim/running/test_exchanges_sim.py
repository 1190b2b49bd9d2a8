"""Exchanges of running work between busy robots in the grid simulator: real agents,
real bids from where each robot is as it drives, on the virtual clock.

Two Huskies at the two ends of a corridor: the first Explore (to the middle) goes to
``a``, the nearer; the second (back to ``a``'s end) arrives two seconds later, when only
``b`` is free, so ``b`` drives the whole corridor while ``a`` drives away from the goal
it could reach at once. No robot is free, so only an exchange of the two busy robots
mends it.
"""

from __future__ import annotations

import anyio
import msgspec
import numpy as np
import pytest
from runwatch import watch_runs

from btcap import Parallel, Sequence, Tree, Wait
from btcap.actors import ActorSystem, ManualClock
from btcap.sim.mission.capabilities import EXPLORE
from btcap.sim.mission.scenario import check_scenario
from btcap.sim.mission.scenariofile import Scenario
from btcap.sim.running.hosts import InProcessHost, agent_config, registry
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.store import MissionState, ObjectStore
from btcap.team.allocation.auction import SingleItemAuction
from btcap.team.runtime.agent import Agent

LENGTH = 101  # cells: a Husky drives 1 m/s, so the corridor takes 100 s


Cell = tuple[int, int]


def scenario(strategy: str, names: list[str]) -> Scenario:
    data = {
        "name": "crossed",
        "objects": 1,
        "robots": [{"name": n, "model": "husky"} for n in names],
        "allocation": {"strategy": strategy, "reevaluate_s": 5.0},
    }
    return check_scenario(msgspec.convert(data, Scenario))


async def drives(
    strategy: str, shape: Cell, robots: dict[str, Cell], goals: list[tuple[Cell, float]]
) -> tuple[list[list[str]], float]:
    """Huskies starting at ``robots`` on an open map of ``shape``, each goal an Explore
    asked for after its delay: the robots that ran each, in order, and when all were
    done."""
    s = scenario(strategy, list(robots))
    grid = GridMap(np.ones(shape, dtype=np.bool_), start=(0, 0), decon_area=(0, 1))
    clock = ManualClock()
    reg = registry()
    state = MissionState(grid, [], rng=np.random.default_rng(0))
    manager = SimulationManager(state, SimConfig(0.5, 0.0, 0.0, 0))
    models = s.models()
    for name, cell in robots.items():
        manager.add_robot(name, models["husky"], cell)
    nodes = [EXPLORE.node_type()(f"g{i}", inputs={"goal": g}) for i, (g, _d) in enumerate(goals)]
    later = [
        Sequence(f"after{i}", children=[Wait(seconds=d), n]) if d > 0 else n
        for i, (n, (_g, d)) in enumerate(zip(nodes, goals, strict=True))
    ]
    tree = Tree(Parallel("all", children=later))
    async with (
        clock.autojump(),
        InProcessHost(s, clock, reg, grid) as host,
        ActorSystem("sim", transport=host.transport("sim"), registry=reg, clock=clock) as sim,
    ):
        sim.spawn(manager, SimulationManager.PATH)
        sim.spawn(ObjectStore(state), ObjectStore.PATH)
        operator = Agent(
            "operator",
            transport=host.transport("operator"),
            clock=clock,
            config=agent_config(s),
            registry=reg,
        )
        async with operator:
            for name in robots:
                manager.robot_up(name)
                host.start(name)
            while operator.repository.providers(EXPLORE.identity) < set(robots):
                await clock.sleep(0.05)
            operator.mission(tree)
            start = clock.now()
            final = await tree.run(2.0, timeout_s=600)
            assert final.name == "SUCCEEDED", final
            took = clock.now() - start
            await tree.shutdown()
    return [n.assignments for n in nodes], took


async def crossed(strategy: str) -> tuple[list[str], list[str], float]:
    """Robots that ran each Explore, in order, and when both had arrived."""
    ran, took = await drives(
        strategy,
        (3, LENGTH),
        {"a": (1, 0), "b": (1, LENGTH - 1)},
        [((1, LENGTH // 2 - 2), 0.0), ((1, 1), 2.0)],
    )
    return ran[0], ran[1], took


@pytest.mark.parametrize("strategy", ["optimal", "auction"])
async def test_two_crossed_huskies_exchange_their_drives(
    strategy: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    twice = watch_runs(monkeypatch)
    with anyio.fail_after(60):
        far, home, took = await crossed(strategy)
    assert (far, home) == (["a", "b"], ["b", "a"])
    # b would have driven the whole corridor (100 s; 161.5 s with the Explore itself)
    assert took < 130
    assert twice == []


async def test_without_exchanges_the_crossed_huskies_drive_on(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(SingleItemAuction, "exchanges", False)
    with anyio.fail_after(60):
        far, home, took = await crossed("optimal")
    assert (far, home) == (["a"], ["b"])
    assert took > 150
