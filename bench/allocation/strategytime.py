"""Mission time per strategy: does the default stay the best, whatever the bids?

``python -m btcap.bench strategytime [--quick] [--scenarios six,known-5] [--seeds 1-10]
[--bids aware,naive] [--hold-down 60]`` runs the real mission (``run_fast``, a virtual
clock) for every registered strategy on:

- ``known-3``, ``known-5``, ``known-8``: the fixed task list of
  :mod:`btcap.bench.allocation.missiontime` (20 objects known at the start, an object loop each,
  huskies and spots in turn, an exact simulation), seeds 1-5;
- ``six``: the paper's mission (exploring finds the objects) with six robots, two of each
  model (``full-team`` grown to 6), 20 objects and 4 object loops, the scenario's delay
  jitter and failure chance, seeds 1-10;

each with the simulated robots' bids as they are (``aware``: a bid for after the work a
robot holds starts where that work leaves it, asking ``bidding_after()``) and as a
capability author who never heard of that would write them (``naive``: every bid from
where the robot stands, ``bids_from_here`` in the team file; the framework then bounds
the later cost itself, :func:`btcap.team.core.bidding.detour`).

The simulation's draws are common random numbers (:mod:`btcap.sim.world.manager`): on one
seed every strategy meets the same durations and failures for the same work.

Reported per scenario and bids: each strategy's mission time (mean, min-max over the
seeds); the default over the best other strategy on the same seed (mean, worst, seeds
over :data:`TARGET`); every strategy's seeds over it, judged the same way (``over``:
how far equally good strategies move a seed); moves, exchanges, hand-overs undone within
60 s, those the hold-down refused and exchanges not made because a task would have come
back. The
target: the default never more than :data:`TARGET` x the best other on any seed, and
nothing undone. Writes ``bench/results/strategytime.json``.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import msgspec

from btcap.bench.allocation.missiontime import TEAM_FILE
from btcap.bench.allocation.missiontime import scenario as known_scenario
from btcap.bench.common import write_result
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import Allocation, Scenario, grow_team, load_scenario
from btcap.sim.running.runner import run_fast
from btcap.sim.world.model import load_team, paper_team
from btcap.team.allocation.strategies import names as strategy_names

__all__ = ["TARGET", "main", "run", "scenario"]

#: The default may be at most this many times the best other strategy's, on any seed.
TARGET = 1.01
SCENARIOS = ("known-3", "known-5", "known-8", "six")
BIDS = ("aware", "naive")
SEEDS = {"six": tuple(range(1, 11))}
KNOWN_SEEDS = (1, 2, 3, 4, 5)
QUICK_SEEDS = (1, 2)
COUNTS = ("moved", "exchanged", "undone", "held_back", "foreseen_back")


def _team_files(tmp: Path) -> dict[tuple[str, str], Path]:
    """The team files: (``known`` | ``six``, bids) -> path."""
    known = tmp / "known.yaml"
    known.write_text(TEAM_FILE)
    out: dict[tuple[str, str], Path] = {("known", "aware"): known}
    for kind, models in (("known", load_team(known)), ("six", paper_team())):
        naive = {n: msgspec.structs.replace(m, bids_from_here=True) for n, m in models.items()}
        path = tmp / f"{kind}-naive.json"
        path.write_bytes(msgspec.json.encode({"models": naive}))
        out[(kind, "naive")] = path
    six = tmp / "six.json"
    six.write_bytes(msgspec.json.encode({"models": paper_team()}))
    out[("six", "aware")] = six
    return out


def scenario(
    name: str, seed: int, strategy: str, team_file: Path, *, hold_down_s: float | None = None
) -> Scenario:
    """Scenario ``name`` (see the module) for ``seed`` and ``strategy``."""
    if name.startswith("known-"):
        s = known_scenario(int(name.removeprefix("known-")), seed, strategy, team_file)
    elif name == "six":
        s = load_scenario(builtin_scenarios()["full-team"])
        grow_team(s, 6)
        s = msgspec.structs.replace(
            s,
            name="six",
            seed=seed,
            objects=20,
            object_workers=4,
            team_file=str(team_file),
            allocation=Allocation(strategy=strategy),
        )
    else:
        raise ValueError(f"scenario {name!r}: expected one of {', '.join(SCENARIOS)}")
    if hold_down_s is not None:
        allocation = msgspec.structs.replace(s.allocation, hold_down_s=hold_down_s)
        s = msgspec.structs.replace(s, allocation=allocation)
    return s


def _seeds(name: str, quick: bool, given: Sequence[int] | None) -> list[int]:
    if given is not None:
        return list(given)
    if quick:
        return list(QUICK_SEEDS)
    return list(SEEDS.get(name, KNOWN_SEEDS))


def run(
    quick: bool = False,
    *,
    scenarios: Sequence[str] = SCENARIOS,
    bids: Sequence[str] = BIDS,
    seeds: Sequence[int] | None = None,
    strategies: Sequence[str] | None = None,
    hold_down_s: float | None = None,
) -> dict[str, Any]:
    """Every strategy's mission time per scenario and bids; see the module."""
    strategies = list(strategies) if strategies is not None else strategy_names()
    default = Allocation().strategy
    load = [os.getloadavg()[0]]
    t0 = time.perf_counter()
    out: dict[str, Any] = {"strategies": strategies, "default": default, "target": TARGET}
    out |= {"hold_down_s": hold_down_s, "rows": {}}
    with tempfile.TemporaryDirectory() as tmp:
        files = _team_files(Path(tmp))
        for name in scenarios:
            kind = "six" if name == "six" else "known"
            for b in bids:
                run_seeds = _seeds(name, quick, seeds)
                row = _row(name, files[(kind, b)], run_seeds, strategies, hold_down_s)
                row["over"] = _over(row)
                out["rows"][f"{name}/{b}"] = row
                load.append(os.getloadavg()[0])
    out["met"] = _met(out, default)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["load_average"] = {"min": round(min(load), 2), "max": round(max(load), 2)}
    _print(out)
    write_result("strategytime", out)
    return out


def _row(
    name: str,
    team_file: Path,
    seeds: list[int],
    strategies: list[str],
    hold_down_s: float | None = None,
) -> dict[str, Any]:
    """One scenario with one kind of bids: times and counts per strategy and seed."""
    times: dict[str, dict[int, float]] = {s: {} for s in strategies}
    counts: dict[str, dict[str, int]] = {s: dict.fromkeys(COUNTS, 0) for s in strategies}
    failed: dict[str, int] = dict.fromkeys(strategies, 0)
    for seed in seeds:
        for strategy in strategies:
            s = scenario(name, seed, strategy, team_file, hold_down_s=hold_down_s)
            result = asyncio.run(run_fast(s))
            times[strategy][seed] = result.mission_time_s
            failed[strategy] += not result.completed
            for c in COUNTS:
                counts[strategy][c] += getattr(result, c)
    return {
        "seeds": seeds,
        "mission_s": {s: {str(k): v for k, v in t.items()} for s, t in times.items()},
        "mean_s": {s: round(statistics.mean(t.values()), 1) for s, t in times.items()},
        "spread_s": {s: [min(t.values()), max(t.values())] for s, t in times.items()},
        "counts": counts,
        "not_completed": failed,
    }


def _vs_best(row: dict[str, Any], default: str) -> list[float]:
    """``default``'s mission time over the best other strategy's, seed by seed."""
    times = row["mission_s"]
    others = [s for s in times if s != default]
    if default not in times or not others:
        return []
    return [times[default][k] / min(times[s][k] for s in others) for k in times[default]]


def _over(row: dict[str, Any]) -> dict[str, int]:
    """Every strategy's seeds over :data:`TARGET` x the best of the others: what the
    target asks against how far equally good decisions move a seed (the noise floor;
    see docs/allocation.md, "The default on every seed")."""
    return {s: sum(x > TARGET for x in _vs_best(row, s)) for s in row["mission_s"]}


def _met(out: dict[str, Any], default: str) -> bool | None:
    ratios = [r for row in out["rows"].values() for r in _vs_best(row, default)]
    if not ratios:
        return None
    undone = sum(c["undone"] for row in out["rows"].values() for c in row["counts"].values())
    return max(ratios) <= TARGET and undone == 0


def _print(out: dict[str, Any]) -> None:
    strategies: list[str] = out["strategies"]
    default: str = out["default"]
    hold = out["hold_down_s"]
    print(
        "mission time per strategy (mean s, min-max over the seeds)"
        + ("" if hold is None else f", hold_down_s {hold}")
    )
    print(f"{'scenario/bids':>14} " + " ".join(f"{s:>17}" for s in strategies))
    for key, row in out["rows"].items():
        cells = []
        for s in strategies:
            lo, hi = row["spread_s"][s]
            lost = row["not_completed"][s]
            cells.append(f"{row['mean_s'][s]:.0f} ({lo:.0f}-{hi:.0f}){'!' * bool(lost)}")
        print(f"{key:>14} " + " ".join(f"{c:>17}" for c in cells))
    print(f"{default} / the best other strategy on the same seed: mean, worst, seeds > {TARGET}")
    for key, row in out["rows"].items():
        r = _vs_best(row, default)
        if r:
            over = sum(x > TARGET for x in r)
            print(f"{key:>14} {statistics.mean(r):.3f} {max(r):.3f} {over}/{len(r)}")
    print(f"every strategy: seeds > {TARGET} x the best of the others")
    for key, row in out["rows"].items():
        seeds = len(row["seeds"])
        print(f"{key:>14} " + " ".join(f"{s} {n}/{seeds}" for s, n in row["over"].items()))
    print("moved / exchanged / undone within 60 s / held back / exchanges foreseen back")
    for key, row in out["rows"].items():
        cells = ["/".join(str(row["counts"][s][c]) for c in COUNTS) for s in strategies]
        print(f"{key:>14} " + " ".join(f"{c:>17}" for c in cells))
    la = out["load_average"]
    met = {True: "met", False: "NOT met", None: "not measured"}[out["met"]]
    print(f"target (default <= {TARGET} x the best other on every seed, nothing undone): {met}")
    print(f"({out['seconds']} s; load average {la['min']}-{la['max']})")


def main(argv: Sequence[str] | None = None, *, quick: bool = False) -> dict[str, Any]:
    """The command line (see the module)."""
    from btcap.bench.allocation.args import seed_list

    p = argparse.ArgumentParser(prog="python -m btcap.bench strategytime", description=__doc__)
    p.add_argument("--quick", action="store_true", default=quick)
    p.add_argument("--scenarios", help=f"some of {','.join(SCENARIOS)}")
    p.add_argument("--bids", help="aware, naive or both")
    p.add_argument("--seeds", type=seed_list, help="scenario seeds, e.g. 1-10")
    p.add_argument("--strategies", help="strategy names, e.g. optimal,auction")
    p.add_argument("--hold-down", type=float, help="hold_down_s of every robot (default 60)")
    a = p.parse_args(argv)
    names = a.scenarios.split(",") if a.scenarios else list(SCENARIOS)
    if bad := [n for n in names if n not in SCENARIOS]:
        p.error(f"--scenarios {','.join(bad)}: expected some of {','.join(SCENARIOS)}")
    bids = a.bids.split(",") if a.bids else list(BIDS)
    if bad := [b for b in bids if b not in BIDS]:
        p.error(f"--bids {','.join(bad)}: expected some of {','.join(BIDS)}")
    strategies = a.strategies.split(",") if a.strategies else None
    if bad := sorted(set(strategies or ()) - set(strategy_names())):
        p.error(f"--strategies {','.join(bad)}: expected some of {','.join(strategy_names())}")
    return run(
        a.quick,
        scenarios=names,
        bids=bids,
        seeds=a.seeds,
        strategies=strategies,
        hold_down_s=a.hold_down,
    )


if __name__ == "__main__":
    main()
