"""What a recording costs a ``--fast`` run: the paper's scenarios run in the fast mode
with no monitor (``none``), a monitor that writes nothing (``monitor``), recording JSON
Lines (``jsonl``), recording MCAP (``mcap``: the monitor's events, the simulated world
drawn for Foxglove) and serving the live Foxglove server with no client (``foxglove``),
taking turns in the same process so load hits all alike.

The verdict (the budget: a recording costs ≤ 5 % of a ``--fast`` run, with and without in
the same turn) is read from pairs: each turn runs every condition once (the order
reversed every other turn), each run's CPU time is divided by the ``none`` run's of its
own turn, and the median of those per-pair ratios is reported with a 95 % percentile
bootstrap interval (:mod:`btcap.bench.speed.paired`), beside the same for wall time and
the 1-minute load average. Load that comes and goes between turns cancels in a pair; a
wall ratio still follows it. With ``--instructions`` each condition also runs once more
under valgrind, which counts the instructions it executes: a ratio no load changes
(the count of a process that only imports and loads the scenario is taken off both).

Reported as well per scenario: the median wall and CPU time of each condition, the
ratios of the medians, the same over the monitor alone (what writing the file adds), the
files' sizes, their size per simulated minute and the MCAP file's size as a share of the
JSON Lines one, and the CPU time spent inside the monitor's batches (sampling the
simulated world, folding, writing the file, serving) as a share of the run's, both
measured in the same run (what the events' hooks cost between batches is not in it).

Run ``python -m btcap.bench recording [--quick] [--scenarios full-team] [--repeats 9]
[--conditions none mcap jsonl] [--instructions]``.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from btcap.bench.common import write_result
from btcap.bench.speed.paired import instructions, median_ci, pair_ratios
from btcap.monitor import Monitor
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast

__all__ = ["main", "run"]

SCENARIOS = ("single-husky", "huskies-bebop-joins", "full-team")
CONDITIONS: tuple[str, ...] = ("none", "monitor", "jsonl", "mcap", "foxglove")


def _timed(f: Callable[..., Any], spent: list[float]) -> Callable[..., Any]:
    """``f``, adding the CPU time of the event loop's thread each call takes to spent[0]."""

    def timed(*args: Any) -> Any:
        t = time.thread_time()
        try:
            return f(*args)
        finally:
            spent[0] += time.thread_time() - t

    return timed


async def _once(
    name: str, condition: str, folder: Path, batches: bool = False
) -> tuple[float, float, float, float]:
    """(wall s, CPU s, simulated s, CPU s inside the monitor's batches) of one fast run of
    ``name`` under ``condition``. The last is measured within the run (thread CPU time
    around every :meth:`Monitor.flush`: sampling the world, folding, writing the file,
    serving), so it holds at any load, unlike a difference of two runs."""
    scenario = load_scenario(builtin_scenarios()[name])
    spent = [0.0]
    wall, cpu = time.perf_counter(), time.process_time()
    if condition == "none":
        result = await run_fast(scenario)
    else:
        path = None if condition in ("monitor", "foxglove") else folder / f"{name}.{condition}"
        live = ("127.0.0.1", 0) if condition == "foxglove" else None
        async with Monitor(port=None, record=path, title=name, foxglove=live) as monitor:
            if batches:  # two thread_time() calls a batch: not free, so only if asked
                monitor.flush = _timed(monitor.flush, spent)  # type: ignore[method-assign]
            result = await run_fast(scenario, monitor=monitor)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu, result.mission_time_s, spent[0]


def main(argv: Sequence[str], quick: bool = False) -> dict[str, Any]:
    p = argparse.ArgumentParser(prog="python -m btcap.bench recording")
    p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), metavar="NAME")
    p.add_argument("--repeats", type=int, help="runs of each condition (default 3, quick 1)")
    p.add_argument("--conditions", nargs="+", choices=CONDITIONS, metavar="NAME",
                   help=f"of {', '.join(CONDITIONS)} (none is always run)")  # fmt: skip
    p.add_argument("--batches", action="store_true",
                   help="time the monitor's batches in each run (costs a little)")  # fmt: skip
    p.add_argument("--instructions", action="store_true",
                   help="count each condition's instructions once under valgrind")  # fmt: skip
    args = p.parse_args(argv)
    conditions = CONDITIONS if args.conditions is None else ("none", *args.conditions)
    return run(quick, scenarios=args.scenarios, repeats=args.repeats,
               conditions=tuple(dict.fromkeys(conditions)), count=args.instructions,
               batches=args.batches)  # fmt: skip


def run(
    quick: bool = False,
    *,
    scenarios: Sequence[str] = SCENARIOS,
    repeats: int | None = None,
    conditions: Sequence[str] = CONDITIONS,
    count: bool = False,
    batches: bool = False,
) -> dict[str, Any]:
    repeats = repeats or (1 if quick else 3)
    if conditions[0] != "none":
        raise ValueError(f"conditions {conditions}: expected none first (the pairs' base)")
    out: dict[str, Any] = {"repeats": repeats, "conditions": list(conditions)}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in scenarios:
            row = _turns(name, conditions, repeats, folder, batches)
            if count:
                row["instructions"] = _count(name, conditions)
            out[name] = row
            print(_line(name, row), flush=True)
    print(f"wrote {write_result('recording', out)}")
    return out


def _turns(
    name: str, conditions: Sequence[str], repeats: int, folder: Path, batches: bool
) -> dict[str, Any]:
    """Every condition once a turn, ``repeats`` turns (the order reversed every other
    turn): medians, paired ratios against ``none`` and the files' sizes."""
    times: dict[str, list[tuple[float, float]]] = {c: [] for c in conditions}
    inside: dict[str, list[float]] = {c: [] for c in conditions}
    sim_s = 0.0
    load = []
    for i in range(repeats):
        for c in conditions if i % 2 == 0 else conditions[::-1]:
            wall, cpu, sim_s, spent = asyncio.run(_once(name, c, folder, batches))
            times[c].append((wall, cpu))
            inside[c].append(spent / cpu)
            load.append(os.getloadavg()[0])
    walls = {c: [w for w, _ in times[c]] for c in conditions}
    cpus = {c: [p for _, p in times[c]] for c in conditions}
    wall_med = {c: statistics.median(walls[c]) for c in conditions}
    cpu_med = {c: statistics.median(cpus[c]) for c in conditions}
    others = [c for c in conditions if c != "none"]
    recorded = [c for c in ("jsonl", "mcap") if c in conditions]
    sizes = {c: (folder / f"{name}.{c}").stat().st_size for c in recorded}
    row: dict[str, Any] = {
        "simulated_s": sim_s,
        "wall_s": wall_med,
        "cpu_s": cpu_med,
        "wall_runs": walls,
        "cpu_runs": cpus,
        "load_1min": [min(load), statistics.median(load), max(load)],
        # the verdict: median of per-pair ratios [median, low, high] (95 % bootstrap)
        "paired_cpu_ratio": {c: median_ci(pair_ratios(cpus[c], cpus["none"])) for c in others},
        "paired_wall_ratio": {c: median_ci(pair_ratios(walls[c], walls["none"])) for c in others},
        **{f"{c}_wall_ratio": wall_med[c] / wall_med["none"] for c in others},
        **{f"{c}_cpu_ratio": cpu_med[c] / cpu_med["none"] for c in others},
        "bytes": sizes,
        "bytes_per_sim_min": {c: sizes[c] / (sim_s / 60) for c in sizes},
    }
    if batches:  # CPU in the monitor's batches as a share of the run's, per run
        row["batch_cpu_share"] = {c: statistics.median(inside[c]) for c in others}
        row["batch_cpu_share_runs"] = {c: inside[c] for c in others}
    if "monitor" in conditions:  # the file alone: over the same monitor writing nothing
        row["paired_cpu_over_monitor"] = {
            c: median_ci(pair_ratios(cpus[c], cpus["monitor"])) for c in others if c != "monitor"
        }
    if len(sizes) == 2:
        row["mcap_over_jsonl"] = sizes["mcap"] / sizes["jsonl"]
    return row


def _line(name: str, row: dict[str, Any]) -> str:
    def ci(r: list[float]) -> str:
        return f"x{r[0]:.3f} [{r[1]:.3f}, {r[2]:.3f}]"

    cpu, wall = row["paired_cpu_ratio"], row["paired_wall_ratio"]
    text = (
        f"{name:20} sim {row['simulated_s']:6.0f} s, wall none {row['wall_s']['none']:5.2f} s"
        f" | load {row['load_1min'][1]:.1f} | per pair, over none: "
        + "; ".join(f"{c} cpu {ci(cpu[c])} wall {ci(wall[c])}" for c in cpu)
    )
    if "batch_cpu_share" in row:
        text += " | CPU in batches: " + ", ".join(
            f"{c} {v:.1%}" for c, v in row["batch_cpu_share"].items()
        )
    if "paired_cpu_over_monitor" in row:
        over = row["paired_cpu_over_monitor"]
        text += " | cpu over monitor alone: " + "; ".join(f"{c} {ci(over[c])}" for c in over)
    counted = row.get("instructions")
    if counted is not None:
        text += " | instructions over none: " + ", ".join(
            f"{c} x{v:.4f}" for c, v in counted["ratio"].items()
        )
    sizes = row["bytes"]
    text += " | " + ", ".join(f"{c} {b / 1024:.0f} KiB" for c, b in sizes.items())
    if "mcap" in sizes:
        text += f", mcap {row['bytes_per_sim_min']['mcap'] / 1024:.1f} KiB per simulated minute"
    return text


def _count(name: str, conditions: Sequence[str]) -> dict[str, Any] | None:
    """Instructions of one run of each condition under valgrind, less those of a process
    that only imports and loads the scenario (``idle``), and their ratios over none."""
    counts: dict[str, int] = {}
    for c in ("idle", *conditions):
        n = instructions([sys.executable, "-m", "btcap.bench.speed.recording", name, c])
        if n is None:
            return None  # no valgrind
        counts[c] = n
    runs = {c: counts[c] - counts["idle"] for c in conditions}
    ratio = {c: runs[c] / runs["none"] for c in conditions if c != "none"}
    return {"counts": counts, "ratio": ratio}


def _child(name: str, condition: str) -> None:
    """One run (what :func:`_count` has valgrind count); ``idle`` loads the scenario only.
    Every condition imports the recorders first, so the counts differ by the run alone
    (MCAP's modules cost some 20 ms of CPU once, whatever the run's length)."""
    import btcap.monitor.mcaprecord  # noqa: F401

    with tempfile.TemporaryDirectory() as tmp:
        if condition == "idle":
            load_scenario(builtin_scenarios()[name])
        else:
            asyncio.run(_once(name, condition, Path(tmp)))


if __name__ == "__main__":
    _child(*sys.argv[1:3])
