"""What a recording costs a ``--fast`` run: the paper's scenarios run in the fast mode
with no monitor (``none``), a monitor that writes nothing (``monitor``), recording JSON
Lines (``jsonl``), recording MCAP (``mcap``: the monitor's events, the simulated world
drawn for Foxglove) and serving the live Foxglove server with no client (``foxglove``, if
the SDK is installed), taking turns in the same process so load hits all alike.

Reported per scenario: the median wall and process CPU time of each condition, the
ratios ``jsonl / none`` and ``mcap / none`` (the budget: ≤ 1.05), the same over the
monitor alone (what writing the file adds), the files' sizes, their size per simulated
minute and the MCAP file's size as a share of the JSON Lines one. On a shared machine
the CPU ratios are the steady ones; wall ratios follow the load. Steadier still, per
run: the CPU time spent inside the monitor's batches (sampling the simulated world,
folding, writing the file, serving) as a share of the run's CPU time, both measured in
the same run (what the events' hooks cost between batches is not in it: the ratios
hold that). The 1-minute load average is reported beside.

Run ``python -m btcap.bench recording [--quick] [--scenarios full-team] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import os
import statistics
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from btcap.bench.common import write_result
from btcap.monitor import Monitor
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast

__all__ = ["main", "run"]

SCENARIOS = ("single-husky", "huskies-bebop-joins", "full-team")
CONDITIONS: tuple[str, ...] = ("none", "monitor", "jsonl", "mcap")
if importlib.util.find_spec("foxglove") is not None:
    CONDITIONS += ("foxglove",)


def _timed(f: Callable[..., Any], spent: list[float]) -> Callable[..., Any]:
    """``f``, adding the CPU time of the event loop's thread each call takes to spent[0]."""

    def timed(*args: Any) -> Any:
        t = time.thread_time()
        try:
            return f(*args)
        finally:
            spent[0] += time.thread_time() - t

    return timed


async def _once(name: str, condition: str, folder: Path) -> tuple[float, float, float, float]:
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
            monitor.flush = _timed(monitor.flush, spent)  # type: ignore[method-assign]
            result = await run_fast(scenario, monitor=monitor)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu, result.mission_time_s, spent[0]


def main(argv: Sequence[str], quick: bool = False) -> dict[str, Any]:
    p = argparse.ArgumentParser(prog="python -m btcap.bench recording")
    p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), metavar="NAME")
    p.add_argument("--repeats", type=int, help="runs of each condition (default 3, quick 1)")
    args = p.parse_args(argv)
    return run(quick, scenarios=args.scenarios, repeats=args.repeats)


def run(
    quick: bool = False, *, scenarios: Sequence[str] = SCENARIOS, repeats: int | None = None
) -> dict[str, Any]:
    repeats = repeats or (1 if quick else 3)
    out: dict[str, Any] = {"repeats": repeats, "conditions": list(CONDITIONS)}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name in scenarios:
            times: dict[str, list[tuple[float, float]]] = {c: [] for c in CONDITIONS}
            inside: dict[str, list[float]] = {c: [] for c in CONDITIONS}
            sim_s = 0.0
            load = []
            for i in range(repeats):
                order = CONDITIONS if i % 2 == 0 else CONDITIONS[::-1]
                for c in order:
                    wall, cpu, sim_s, spent = asyncio.run(_once(name, c, folder))
                    times[c].append((wall, cpu))
                    inside[c].append(spent / cpu)
                    load.append(os.getloadavg()[0])
            wall_med = {c: statistics.median(w for w, _ in times[c]) for c in CONDITIONS}
            cpu_med = {c: statistics.median(p for _, p in times[c]) for c in CONDITIONS}
            # CPU in the monitor's batches as a share of the run's, per run (load-proof)
            share = {c: statistics.median(inside[c]) for c in CONDITIONS[1:]}
            sizes = {c: (folder / f"{name}.{c}").stat().st_size for c in ("jsonl", "mcap")}
            shown = CONDITIONS[2:]
            row: dict[str, Any] = {
                "simulated_s": sim_s,
                "wall_s": wall_med,
                "cpu_s": cpu_med,
                "wall_runs": {c: [w for w, _ in times[c]] for c in CONDITIONS},
                "cpu_runs": {c: [p for _, p in times[c]] for c in CONDITIONS},
                "batch_cpu_share": share,
                "batch_cpu_share_runs": {c: inside[c] for c in CONDITIONS[1:]},
                "load_1min": [min(load), statistics.median(load), max(load)],
                **{f"{c}_wall_ratio": wall_med[c] / wall_med["none"] for c in shown},
                **{f"{c}_cpu_ratio": cpu_med[c] / cpu_med["none"] for c in shown},
                # the file alone: recording against the same monitor writing nothing
                **{f"{c}_over_monitor_cpu": cpu_med[c] / cpu_med["monitor"] for c in shown},
                "bytes": sizes,
                "bytes_per_sim_min": {c: sizes[c] / (sim_s / 60) for c in sizes},
                "mcap_over_jsonl": sizes["mcap"] / sizes["jsonl"],
            }
            out[name] = row
            print(
                f"{name:20} sim {sim_s:6.0f} s | wall none {wall_med['none']:6.2f} s, "
                + ", ".join(f"{c} x{row[f'{c}_wall_ratio']:.3f}" for c in shown)
                + " | cpu "
                + ", ".join(f"{c} x{row[f'{c}_cpu_ratio']:.3f}" for c in shown)
                + ", over monitor alone: "
                + ", ".join(f"{c} x{row[f'{c}_over_monitor_cpu']:.3f}" for c in shown)
                + " | CPU in batches, share of the run: "
                + ", ".join(f"{c} {share[c]:.1%}" for c in CONDITIONS[1:])
                + f" | load {statistics.median(load):.1f}"
                + " | "
                f"{sizes['jsonl'] / 1024:.0f} KiB jsonl, {sizes['mcap'] / 1024:.0f} KiB mcap "
                f"({row['mcap_over_jsonl']:.2f}), "
                f"{row['bytes_per_sim_min']['mcap'] / 1024:.1f} KiB mcap per simulated minute",
                flush=True,
            )
    print(f"wrote {write_result('recording', out)}")
    return out
