"""Allocation quality: sequential single-item auctions vs the exact optimum.

On seeded random instances (robots and tasks on a cave map, each robot taking at most one
task, costs = path length x the robot's cost factor + the task's duration on that robot,
as bids are computed in the mission), the auction assigns tasks in arrival order, each to
the cheapest free bidder, as btcap's auctioneer does; the optimum comes from
``scipy.optimize.linear_sum_assignment``. Reported: the ratio of total costs.
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from btcap.bench.common import write_result
from btcap.sim.distance import DistanceCache, path_length
from btcap.sim.grid import GridMap
from btcap.team.core.auction import Auction
from btcap.team.core.ids import AuctionId
from btcap.team.messages import Bid

__all__ = ["run"]


def _instance(
    grid: GridMap, rng: np.random.Generator, robots: int, tasks: int
) -> np.ndarray[Any, np.dtype[np.float64]]:
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


def _auction_total(cost: np.ndarray[Any, np.dtype[np.float64]]) -> float:
    """Tasks auctioned one after the other; a robot that won is busy (declines)."""
    robots, tasks = cost.shape
    free = set(range(robots))
    total = 0.0
    for t in range(tasks):
        a = Auction(AuctionId("bench", t), "Task", frozenset(f"r{r}" for r in range(robots)), 1.0)
        for r in range(robots):
            if r in free:
                a.offer(Bid(a.id, f"r{r}", float(cost[r, t]), "impl"))
        ranking = a.outcome().ranking
        if not ranking:
            break
        winner = int(ranking[0].robot[1:])
        free.discard(winner)
        total += float(cost[winner, t])
    return total


def run(quick: bool = False) -> dict[str, Any]:
    grid = GridMap.generate_cave(80, 60, seed=3)
    sizes = [(5, 5), (10, 10), (20, 10)] if quick else [(5, 5), (10, 10), (20, 10), (30, 30)]
    instances = 10 if quick else 30
    out: dict[str, Any] = {"instances": instances, "ratio": {}}
    t0 = time.perf_counter()
    for robots, tasks in sizes:
        ratios = []
        for seed in range(instances):
            cost = _instance(grid, np.random.default_rng(seed), robots, tasks)
            rows, cols = linear_sum_assignment(cost)
            optimum = float(cost[rows, cols].sum())
            ratios.append(_auction_total(cost) / optimum)
        out["ratio"][f"{robots}x{tasks}"] = {
            "mean": round(statistics.mean(ratios), 4),
            "max": round(max(ratios), 4),
        }
    print("auction / optimum total cost (1.0 = optimal)")
    for key, r in out["ratio"].items():
        print(f"  robots x tasks {key:>6}: mean {r['mean']:.3f}  max {r['max']:.3f}")
    out["seconds"] = round(time.perf_counter() - t0, 2)
    write_result("allocation", out)
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    run(quick=p.parse_args().quick)
