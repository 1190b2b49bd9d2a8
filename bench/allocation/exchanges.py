"""What exchanges of running work between busy robots would gain: an offline estimate.

``python -m btcap.bench.allocation.exchanges [--seeds 1000-1019] [--map cave:7] [--dynamic]`` runs a
strategy's real team on the allocation bench's instances (:mod:`btcap.bench.allocation.optimum`),
then applies :func:`btcap.team.core.exchange.find_exchanges` to its final allocation until
no exchange is left, and prints total cost / optimum before and after. The bench's bids
are static (a task costs a robot the same while it runs), so this is what exchanges
would reach with full knowledge once the team is busy. Re-evaluation carries out swaps
and chains of three at run time (``btcap.team.runtime.moving``), choosing which to try
from the bids it has heard rather than from every robot's cost, one re-evaluation at a
time; the allocation bench's dynamic rows measure that (see docs/allocation.md).
"""

from __future__ import annotations

import argparse
import asyncio
from collections.abc import Sequence

import numpy as np

from btcap.bench.allocation.args import load_map, seed_list
from btcap.bench.allocation.optimum import (
    Costs,
    Events,
    allocate,
    ratios,
    seeded_events,
    seeded_instance,
)
from btcap.sim.world.grid import GridMap
from btcap.team.core.exchange import Running, find_exchanges
from btcap.team.ids import ExecutionId

__all__ = ["exchanged", "main"]

MARGINS = (0.2, 0.1, 0.05)


def exchanged(cost: Costs, final: Sequence[int], margin: float, chain: int) -> list[int]:
    """``final`` (robot per task, -1: none) after exchanges, round after round."""
    got = list(final)
    ids = [ExecutionId("origin", f"t{t}", t) for t in range(len(got))]
    while True:
        held = [(t, r) for t, r in enumerate(got) if r >= 0]
        running = [Running(ids[t], str(r), float(cost[r, t])) for t, r in held]
        cross = {(str(r), ids[t]): float(cost[r, t]) for _, r in held for t, _ in held}
        found = find_exchanges(running, cross, margin, chain=chain)
        if not found:
            return got
        for ex in found:
            for leg in ex.legs:
                got[leg.execution.number] = int(leg.to)


def _row(label: str, values: dict[str, list[float]]) -> None:
    cells = [f"{k} {np.mean(v):.3f} ({max(v):.3f})" for k, v in values.items()]
    print(f"{label}: " + "; ".join(cells), flush=True)


def _measure(cost: Costs, final: list[int], alive: list[int], out: dict[str, list[float]]) -> None:
    out.setdefault("as run", []).append(ratios(cost, final, alive)[0])
    for margin in MARGINS:
        for chain in (2, 3):
            after = exchanged(cost, final, margin, chain)
            out.setdefault(f"m{margin} c{chain}", []).append(ratios(cost, after, alive)[0])


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(
        prog="python -m btcap.bench.allocation.exchanges", description=__doc__
    )
    p.add_argument("--seeds", type=seed_list, default=list(range(20)))
    p.add_argument("--map", type=load_map, default=None)
    p.add_argument("--strategy", default="auction")
    p.add_argument("--dynamic", action="store_true", help="the dynamic cases (25 x 20)")
    a = p.parse_args(argv)
    grid = a.map if a.map is not None else GridMap.generate_cave(80, 60, seed=3)
    print(f"{a.strategy} on {grid.source}; mean (worst) total cost / optimum")
    if not a.dynamic:
        for r, t in ((20, 20), (50, 50)):
            out: dict[str, list[float]] = {}
            for seed in a.seeds:
                cost = seeded_instance(grid, np.random.default_rng(seed), r, t)
                got = asyncio.run(allocate(cost, a.strategy, Events((0.0,) * t), None, seed))
                _measure(cost, got.final, list(range(r)), out)
            _row(f"{r} x {t}", out)
        return
    robots, tasks = 25, 20
    for case, size in (("arrivals", 0), ("failures", 3), ("joins", robots - tasks)):
        out = {}
        for seed in a.seeds[:10]:
            rng = np.random.default_rng(1000 + seed)
            cost = seeded_instance(grid, rng, robots, tasks)
            events = seeded_events(rng, case, tasks, size)
            done = asyncio.run(allocate(cost, a.strategy, events, 30.0, seed))
            _measure(cost, done.final, [i for i in range(robots) if i not in done.failed], out)
        _row(case, out)


if __name__ == "__main__":
    main()
