"""Grid-world benchmark: vectorised robot steps vs a per-robot Python loop, distance fields.

Both steppers run the same seeded worlds (a 120x80 cave at 1 m, the mission's size;
robots at random cells, 0.5-3 m/s, goals drawn from 32 shared cells, dt = 0.5 s) for
the same number of steps from the same start, and must end in identical states.
"""

from __future__ import annotations

import argparse
import gc
import json
import statistics
import time
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from btcap.bench.common import RESULTS
from btcap.sim import GridMap, World, distance_field

__all__ = ["run"]

ROBOT_COUNTS = (10, 100, 1000)
CAVE_SIZES = (256, 512)
DT_S = 0.5
STEPS = 20
GOAL_POOL = 32
SEED = 7

Stepper = Callable[[World, float], NDArray[np.intp]]


def _world(grid: GridMap, robots: int, seed: int) -> World:
    rng = np.random.default_rng(seed)
    world = World(grid, cache_size=2 * GOAL_POOL)
    goals = grid.random_free_cells(GOAL_POOL, rng)
    for cell in grid.random_free_cells(robots, rng, replace=True):
        world.add_robot(
            cell,
            speed_mps=float(rng.uniform(0.5, 3.0)),
            cost_factor=float(rng.choice([2.0, 1.25, 1.0])),
        )
    for i in range(robots):
        world.set_goal(i, goals[rng.integers(GOAL_POOL)])
    return world


def _run_steps(world: World, stepper: Stepper) -> list[float]:
    """Seconds of each of ``STEPS`` steps of a fresh copy of ``world``.

    Steps are timed one by one so the median resists bursts of load from other
    processes on the machine (a whole-run average does not).
    """
    twin = world.copy()
    clock = time.perf_counter
    samples = []
    for _ in range(STEPS):
        started = clock()
        stepper(twin, DT_S)
        samples.append(clock() - started)
    return samples


def _same_state(a: World, b: World) -> bool:
    return all(
        np.array_equal(x, y)
        for x, y in (
            (a.positions, b.positions),
            (a.moving, b.moving),
            (a.progress, b.progress),
            (a.travelled_m, b.travelled_m),
        )
    )


def _check_equal(world: World) -> None:
    vectorised, loop = world.copy(), world.copy()
    for _ in range(STEPS):
        arrived_v = vectorised.step(DT_S)
        arrived_l = loop.step_loop(DT_S)
        if not (np.array_equal(arrived_v, arrived_l) and _same_state(vectorised, loop)):
            raise AssertionError("vectorised step and loop step disagree")


def _step_times(repeats: int) -> dict[str, dict[str, float]]:
    grid = GridMap.generate_cave(120, 80, seed=SEED)
    result: dict[str, dict[str, float]] = {"vectorised": {}, "loop": {}}
    for robots in ROBOT_COUNTS:
        world = _world(grid, robots, SEED + robots)
        _check_equal(world)
        samples: dict[str, list[float]] = {"vectorised": [], "loop": []}
        for _ in range(repeats):
            samples["vectorised"] += _run_steps(world, World.step)
            samples["loop"] += _run_steps(world, World.step_loop)
        for name, values in samples.items():
            result[name][str(robots)] = round(statistics.median(values) * 1e6, 2)
    return result


def _distance_field_times(repeats: int) -> dict[str, float]:
    result: dict[str, float] = {}
    for size in CAVE_SIZES:
        grid = GridMap.generate_cave(size, size, seed=SEED)
        distance_field(grid.free, grid.start)  # warm-up
        samples = []
        for _ in range(repeats):
            started = time.perf_counter()
            distance_field(grid.free, grid.start)
            samples.append(time.perf_counter() - started)
        result[str(size)] = round(statistics.median(samples) * 1e3, 3)
    return result


def run(quick: bool = False) -> dict[str, object]:
    """Measure, write ``bench/results/sim.json``, print a table, return the result."""
    repeats = 7 if quick else 31
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        steps = _step_times(repeats)
        fields = _distance_field_times(repeats)
    finally:
        if gc_was_enabled:
            gc.enable()
    speedup = round(steps["loop"]["1000"] / steps["vectorised"]["1000"], 1)
    result: dict[str, object] = {
        "step_us": steps,
        "speedup_1000": speedup,
        "distance_field_ms": fields,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "sim.json").write_text(json.dumps(result, indent=2) + "\n")
    _print_table(steps, speedup, fields)
    return result


def _print_table(
    steps: dict[str, dict[str, float]], speedup: float, fields: dict[str, float]
) -> None:
    print(f"grid world step (120x80 cave, dt={DT_S} s, median us per step)")
    print(f"{'robots':>8} {'vectorised':>12} {'loop':>12} {'speed-up':>9}")
    for robots in map(str, ROBOT_COUNTS):
        vec, loop = steps["vectorised"][robots], steps["loop"][robots]
        print(f"{robots:>8} {vec:>12.1f} {loop:>12.1f} {loop / vec:>8.1f}x")
    print(f"speed-up at 1000 robots: {speedup}x (target >= 50x)")
    for size, ms in fields.items():
        print(f"distance field {size}x{size} cave: {ms:.2f} ms (median)")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m btcap.bench.speed.sim", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer repeats (< 20 s)")
    args = parser.parse_args(argv)
    run(quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
