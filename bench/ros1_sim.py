"""The simulator behind ROS 1 (as the paper set it up) against the direct simulation: the
same mission, same run.

``make bench-ros1-sim`` (``python -m btcap.bench.ros1_sim [--quick]`` in .venv-ros1): the
paper's full-team mission on the wall clock at a speed-up, once with the robots asking the
simulation manager directly (actor messages in one process) and once with every robot
reached through ROS 1 (``run_scenario(ros1=True)``: each move a ``move_base`` goal, each
operation a service call, every position a topic message, through a rosmaster of the run's
own on loopback and a rospy process per robot and for the simulation), alternately, the
same number of times each. Reported per speed-up, as :mod:`btcap.bench.ros_sim` does for
ROS 2: wall time and mission time of each, the ROS 1 / direct ratios of their medians,
whether every run completed with the direct run's outcome, and the load average. The ROS 1
run's wall time includes starting the master and the rospy processes (a second or two
each, in parallel) and stopping them.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import time
from collections.abc import Sequence
from typing import Any

from btcap.bench.common import write_result
from btcap.bench.ros_sim import OUTCOME, SCENARIO, _median
from btcap.sim.catalog import builtin_scenarios
from btcap.sim.metrics import MissionResult
from btcap.sim.runner import run_fast, run_scenario
from btcap.sim.scenario import load_scenario

__all__ = ["main", "run"]


async def _once(speedup: float, ros1: bool) -> tuple[float, MissionResult]:
    s = load_scenario(builtin_scenarios()[SCENARIO])
    s.speedup = speedup
    t = time.perf_counter()
    result = await run_scenario(s, ros1=ros1)
    return time.perf_counter() - t, result


def run(quick: bool = False, speedups: Sequence[float] | None = None) -> dict[str, Any]:
    speedups = speedups or ((100.0,) if quick else (50.0, 100.0))
    repeats = 1 if quick else 3
    os.environ.setdefault("ROS_IP", "127.0.0.1")  # every rospy process on loopback
    reference = asyncio.run(run_fast(load_scenario(builtin_scenarios()[SCENARIO])))
    want = {k: reference.summary[k] for k in OUTCOME}
    load = [os.getloadavg()[0]]
    rows: dict[str, Any] = {}
    for speedup in speedups:
        runs: dict[str, list[tuple[float, MissionResult]]] = {"direct": [], "ros1": []}
        for _ in range(repeats):
            for mode in ("direct", "ros1"):
                runs[mode].append(asyncio.run(_once(speedup, mode == "ros1")))
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
            row[f"ratio_{key}"] = round(_median(row["ros1"][key]) / _median(row["direct"][key]), 3)
        rows[f"{speedup:g}"] = row
        print(
            f"speed-up {speedup:g}: wall ros1/direct {row['ratio_wall_s']:.2f} "
            f"(median {_median(row['ros1']['wall_s']):.1f} / "
            f"{_median(row['direct']['wall_s']):.1f} s), mission time ratio "
            f"{row['ratio_mission_s']:.2f} ({_median(row['ros1']['mission_s']):.0f} / "
            f"{_median(row['direct']['mission_s']):.0f} s; fast mode "
            f"{reference.mission_time_s:.0f} s); same outcome: ros1 "
            f"{row['ros1']['same_outcome']}, direct {row['direct']['same_outcome']}",
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
    print(f"wrote {write_result('ros1_sim', data)}")
    return data


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m btcap.bench.ros1_sim", description=__doc__)
    p.add_argument("--quick", action="store_true", help="speed-up 100 only, one run each")
    p.add_argument("--speedup", type=float, action="append", help="speed-ups to run")
    args = p.parse_args(argv)
    run(quick=args.quick, speedups=args.speedup)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
