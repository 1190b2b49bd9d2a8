"""What a recording costs a ``--fast`` run: the paper's scenarios run in the fast mode
with no monitor (``none``), a monitor that writes nothing (``monitor``), recording JSON
Lines (``jsonl``), recording MCAP (``mcap``: the monitor's events, the simulated world
drawn for Foxglove) and serving the live Foxglove server with no client (``foxglove``, if
the SDK is installed), taking turns in the same process so load hits all alike.

Reported per scenario: the median wall and process CPU time of each condition, the
ratios ``jsonl / none`` and ``mcap / none`` (the budget: ≤ 1.05), the same over the
monitor alone (what writing the file adds), the files' sizes, their size per simulated
minute and the MCAP file's size as a share of the JSON Lines one. On a shared machine
the CPU ratios are the steady ones; wall ratios follow the load.

Run ``python -m btcap.bench recording [--quick] [--scenarios full-team] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from btcap.bench.common import write_result
from btcap.monitor import Monitor
from btcap.sim.catalog import builtin_scenarios
from btcap.sim.runner import run_fast
from btcap.sim.scenario import load_scenario

__all__ = ["main", "run"]

SCENARIOS = ("single-husky", "huskies-bebop-joins", "full-team")
CONDITIONS: tuple[str, ...] = ("none", "monitor", "jsonl", "mcap")
if importlib.util.find_spec("foxglove") is not None:
    CONDITIONS += ("foxglove",)


async def _once(name: str, condition: str, folder: Path) -> tuple[float, float, float]:
    """(wall s, CPU s, simulated s) of one fast run of ``name`` under ``condition``."""
    scenario = load_scenario(builtin_scenarios()[name])
    wall, cpu = time.perf_counter(), time.process_time()
    if condition == "none":
        result = await run_fast(scenario)
    else:
        path = None if condition in ("monitor", "foxglove") else folder / f"{name}.{condition}"
        live = ("127.0.0.1", 0) if condition == "foxglove" else None
        async with Monitor(port=None, record=path, title=name, foxglove=live) as monitor:
            result = await run_fast(scenario, monitor=monitor)
    return time.perf_counter() - wall, time.process_time() - cpu, result.mission_time_s


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
            sim_s = 0.0
            for i in range(repeats):
                order = CONDITIONS if i % 2 == 0 else CONDITIONS[::-1]
                for c in order:
                    wall, cpu, sim_s = asyncio.run(_once(name, c, folder))
                    times[c].append((wall, cpu))
            wall_med = {c: statistics.median(w for w, _ in times[c]) for c in CONDITIONS}
            cpu_med = {c: statistics.median(p for _, p in times[c]) for c in CONDITIONS}
            sizes = {c: (folder / f"{name}.{c}").stat().st_size for c in ("jsonl", "mcap")}
            shown = CONDITIONS[2:]
            row: dict[str, Any] = {
                "simulated_s": sim_s,
                "wall_s": wall_med,
                "cpu_s": cpu_med,
                "wall_runs": {c: [w for w, _ in times[c]] for c in CONDITIONS},
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
                + " | "
                f"{sizes['jsonl'] / 1024:.0f} KiB jsonl, {sizes['mcap'] / 1024:.0f} KiB mcap "
                f"({row['mcap_over_jsonl']:.2f}), "
                f"{row['bytes_per_sim_min']['mcap'] / 1024:.1f} KiB mcap per simulated minute",
                flush=True,
            )
    print(f"wrote {write_result('recording', out)}")
    return out
