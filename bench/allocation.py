"""Allocation quality of the real assignment code against the exact optimum.

On seeded random instances (robots and tasks on a cave map; cost = path length x the
robot's cost factor + the task's duration on that robot, as bids are computed in the
mission), a team of agents runs in one process on a virtual clock: one robot per agent,
each bidding those costs, and an origin whose mission asks for every task at once. Each
strategy of the auctioneer (``arrival``, ``auction``, ``optimal``; see
``btcap.team.core.planning``) assigns them through real calls for bids, bids and awards;
the optimum comes from ``scipy.optimize.linear_sum_assignment``. Reported: the ratio of
total costs (1.0 = optimal), and of makespans (the largest cost any robot took on).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from collections.abc import Mapping
from contextlib import AsyncExitStack
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from btcap import AlwaysRunning, Parallel, Sequence, Tree
from btcap.actors import ManualClock
from btcap.bench.common import write_result
from btcap.sim.distance import DistanceCache, path_length
from btcap.sim.grid import GridMap
from btcap.team.agent import Agent, AgentConfig
from btcap.team.capability import CapabilityInterface
from btcap.team.implementation import Implementation
from btcap.team.protocol import protocol_registry
from btcap.transports import InProcessNetwork

__all__ = ["run"]

TASK = CapabilityInterface("Task", inputs={"task": int}, description="go and do task #task")
STRATEGIES = ("arrival", "auction", "sequential", "optimal")

Costs = np.ndarray[Any, np.dtype[np.float64]]


def _instance(grid: GridMap, rng: np.random.Generator, robots: int, tasks: int) -> Costs:
    cache = DistanceCache(grid.free, maxsize=tasks + 1)
    starts = grid.random_free_cells(robots, rng, replace=True)
    goals = grid.random_free_cells(tasks, rng, replace=True)
    factor = rng.choice([1.0, 1.25, 2.0], size=robots)
    duration = rng.uniform(2.0, 60.0, size=(robots, tasks))
    cost = np.empty((robots, tasks))
    for t, goal in enumerate(goals):
        field = cache.get(goal)
        for r, start in enumerate(starts):
            cost[r, t] = path_length(field, start, grid.cell_size_m) * factor[r] + duration[r, t]
    return cost


def _implementation(costs: Mapping[int, float]) -> Implementation:
    def build() -> Tree:
        bridge, _ = TASK.bridge_types()
        return Tree(Sequence("impl", children=[bridge(name="in"), AlwaysRunning("work")]))

    return Implementation("do-task", TASK, build, (), lambda inputs: costs[inputs["task"]])


async def _assign(cost: Costs, strategy: str) -> list[int]:
    """Which robot the real team gives each task to (every task asked for at once)."""
    robots, tasks = cost.shape
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry(), encode=False)
    cfg = AgentConfig(heartbeat_s=1.0, failure_timeout_s=30.0, reevaluate_s=None, strategy=strategy)
    async with clock.autojump(), AsyncExitStack() as stack:
        names = [f"r{r:02d}" for r in range(robots)]
        for r, name in enumerate(names):
            impl = _implementation({t: float(cost[r, t]) for t in range(tasks)})
            agent = Agent(
                name,
                transport=net.transport(name),
                clock=clock,
                implementations=[impl],
                config=cfg,
            )
            await stack.enter_async_context(agent)
        origin = await stack.enter_async_context(
            Agent("origin", transport=net.transport("origin"), clock=clock, config=cfg)
        )
        while len(origin.repository.providers(TASK.identity)) < robots:
            await clock.sleep(0.1)
        nodes = [TASK.node_type()(f"t{t}", inputs={"task": t}) for t in range(tasks)]
        tree = origin.mission(Parallel("all", children=nodes))
        while not all(n.assignments for n in nodes):
            tree.tick()
            await clock.sleep(0.05)
        winners = [names.index(n.assignments[0]) for n in nodes]
        await tree.shutdown()
    return winners


def run(quick: bool = False) -> dict[str, Any]:
    grid = GridMap.generate_cave(80, 60, seed=3)
    sizes = [(5, 5), (10, 10)] if quick else [(5, 5), (10, 10), (20, 20)]
    instances = 5 if quick else 20
    out: dict[str, Any] = {"instances": instances, "cost_ratio": {}, "makespan_ratio": {}}
    t0 = time.perf_counter()
    for robots, tasks in sizes:
        key = f"{robots}x{tasks}"
        ratios: dict[str, list[float]] = {s: [] for s in STRATEGIES}
        spans: dict[str, list[float]] = {s: [] for s in STRATEGIES}
        for seed in range(instances):
            cost = _instance(grid, np.random.default_rng(seed), robots, tasks)
            rows, cols = linear_sum_assignment(cost)
            optimum = float(cost[rows, cols].sum())
            best_span = float(cost[rows, cols].max())
            for strategy in STRATEGIES:
                winners = asyncio.run(_assign(cost, strategy))
                taken = [float(cost[r, t]) for t, r in enumerate(winners)]
                ratios[strategy].append(sum(taken) / optimum)
                spans[strategy].append(max(taken) / best_span)
        for name, table in (("cost_ratio", ratios), ("makespan_ratio", spans)):
            out[name][key] = {
                s: {"mean": round(statistics.mean(v), 4), "max": round(max(v), 4)}
                for s, v in table.items()
            }
    out["seconds"] = round(time.perf_counter() - t0, 2)
    print(f"total cost / optimum (1.0 = optimal), real agents, {instances} seeded instances")
    print(f"{'robots x tasks':>15} " + " ".join(f"{s:>16}" for s in STRATEGIES))
    for key, by in out["cost_ratio"].items():
        cells = " ".join(f"{by[s]['mean']:7.3f} (max {by[s]['max']:.2f})" for s in STRATEGIES)
        print(f"{key:>15} {cells}")
    print("makespan / that of the least-total-cost assignment")
    for key, by in out["makespan_ratio"].items():
        cells = " ".join(f"{by[s]['mean']:7.3f} (max {by[s]['max']:.2f})" for s in STRATEGIES)
        print(f"{key:>15} {cells}")
    write_result("allocation", out)
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    run(quick=p.parse_args().quick)
