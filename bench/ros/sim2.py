"""The simulator behind ROS 2 against the direct simulation: the same mission, same run.

``make bench-ros-sim`` (``python -m btcap.bench.ros.sim2 [--quick]`` in .venv-ros, inside a
private network namespace): the paper's full-team mission on the wall clock at a speed-up,
once with the robots asking the simulation manager directly (actor messages in one
process) and once with every robot reached through ROS 2 (``run_scenario(ros2=True)``:
each move and operation an action goal over DDS, every position a topic message),
alternately, the same number of times each. Reported per speed-up: wall time and mission
time (clock seconds) of each, the ROS / direct ratios of their medians, whether every run
completed with the direct run's outcome (objects found, identified, contaminated,
decontaminated, coverage), and the load average while it ran. The deterministic fast
mode's mission time of the same scenario and seed is the reference beside them.

On the wall clock the mission time is not fixed: the clock runs on while messages are on
their way, so each wall millisecond a goal, a result or a state message waits is
``speed-up`` milliseconds of mission time, ROS's and the direct run's alike. What it
costs ROS shows as the mission time ratio, which grows with the speed-up and with load.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any

from btcap.bench.common import write_result
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.metrics import MissionResult
from btcap.sim.running.runner import run_fast, run_scenario

__all__ = ["cli", "compare", "main", "run"]

SCENARIO = "full-team"
OUTCOME = ("objects", "found", "identified", "contaminated", "decontaminated", "coverage")


async def _once(speedup: float, mode: str) -> tuple[float, MissionResult]:
    """One run, ``mode`` ``direct``, ``ros1`` or ``ros2``."""
    s = load_scenario(builtin_scenarios()[SCENARIO])
    s.speedup = speedup
    t = time.perf_counter()
    result = await run_scenario(s, ros1=mode == "ros1", ros2=mode == "ros2")
    return time.perf_counter() - t, result


def _median(xs: list[float]) -> float:
    return statistics.median(xs) if xs else float("nan")


def compare(backend: str, result: str, speedups: Sequence[float], repeats: int) -> dict[str, Any]:
    """The mission through ``backend`` (``ros1`` or ``ros2``: :func:`run_scenario`'s
    keyword) against the direct run, alternately, ``repeats`` times each per speed-up;
    written as ``result``. Shared by this bench and :mod:`btcap.bench.ros.sim1`."""
    reference = asyncio.run(run_fast(load_scenario(builtin_scenarios()[SCENARIO])))
    want = {k: reference.summary[k] for k in OUTCOME}
    load = [os.getloadavg()[0]]
    rows: dict[str, Any] = {}
    for speedup in speedups:
        runs: dict[str, list[tuple[float, MissionResult]]] = {"direct": [], backend: []}
        for _ in range(repeats):
            for mode in ("direct", backend):
                runs[mode].append(asyncio.run(_once(speedup, mode)))
                load.append(os.getloadavg()[0])
        row: dict[str, Any] = {}
        for mode, got in runs.items():
            row[mode] = {
                "wall_s": [round(w, 2) for w, _ in got],
                "mission_s": [round(r.mission_time_s, 1) for _, r in got],
                "same_outcome": all(
                    r.completed and {k: r.summary[k] for k in OUTCOME} == want for _, r in got
                ),
            }
        for key in ("wall_s", "mission_s"):
            row[f"ratio_{key}"] = round(_median(row[backend][key]) / _median(row["direct"][key]), 3)
        rows[f"{speedup:g}"] = row
        print(
            f"speed-up {speedup:g}: wall {backend}/direct {row['ratio_wall_s']:.2f} "
            f"(median {_median(row[backend]['wall_s']):.1f} / "
            f"{_median(row['direct']['wall_s']):.1f} s), mission time ratio "
            f"{row['ratio_mission_s']:.2f} ({_median(row[backend]['mission_s']):.0f} / "
            f"{_median(row['direct']['mission_s']):.0f} s; fast mode "
            f"{reference.mission_time_s:.0f} s); same outcome: {backend} "
            f"{row[backend]['same_outcome']}, direct {row['direct']['same_outcome']}",
            flush=True,
        )
    data = {
        "scenario": SCENARIO,
        "repeats": repeats,
        "fast_mode_mission_s": round(reference.mission_time_s, 1),
        "outcome": want,
        "speedups": rows,
        "load_avg_1m": {"min": min(load), "max": max(load)},
    }
    print(f"wrote {write_result(result, data)}")
    return data


def run(quick: bool = False, speedups: Sequence[float] | None = None) -> dict[str, Any]:
    speedups = speedups or ((100.0,) if quick else (50.0, 100.0))
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))
    return compare("ros2", "ros_sim", speedups, 1 if quick else 3)


def cli(
    bench: Callable[..., dict[str, Any]], prog: str, doc: str | None, argv: Sequence[str] | None
) -> int:
    """The command line of this bench and :mod:`btcap.bench.ros.sim1`: ``--quick``,
    ``--speedup`` given to ``bench`` (their ``run``)."""
    p = argparse.ArgumentParser(prog=prog, description=doc)
    p.add_argument("--quick", action="store_true", help="speed-up 100 only, one run each")
    p.add_argument("--speedup", type=float, action="append", help="speed-ups to run")
    args = p.parse_args(argv)
    bench(quick=args.quick, speedups=args.speedup)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli(run, "python -m btcap.bench.ros.sim2", __doc__, argv)


if __name__ == "__main__":
    raise SystemExit(main())
