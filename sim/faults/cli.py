"""``btcap sim-test``: deterministic simulation testing of the whole team.

Each seed is a plan (:func:`btcap.sim.faults.plan.plan_for`): real agents on a faulty
network on the virtual clock, invariants checked after every step. A failing seed prints
the command that replays it and a shrunken trace. Registered from :mod:`btcap.sim.cli`;
the simulation is imported only when the command runs, so ``btcap --help`` stays fast.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from btcap.cli import CliError, configure_logging

if TYPE_CHECKING:
    from btcap.sim.faults.plan import Plan
    from btcap.sim.faults.run import Outcome

__all__ = ["Draw", "add_parser", "parse_robots", "sim_test_command"]


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sim-test",
        help="deterministic simulation test of the team under seeded network faults",
        description="Run real agents on a seeded faulty network (drops, delays, reordering, "
        "duplicates, partitions, frozen, crashed, joining and leaving robots) on the virtual "
        "clock, checking after every step that no task ever runs on two robots at once "
        "(crashes, freezes and partitions alike), that nothing is credited to a robot "
        "declared failed, that tables stay bounded, and that the mission completes once the "
        "faults heal. A failing seed "
        "prints the command that replays it and a shrunken trace.",
    )
    p.add_argument("--seeds", type=int, default=100, metavar="N", help="seeds to run (100)")
    p.add_argument("--start", type=int, default=0, metavar="S", help="first seed (0)")
    p.add_argument("--seed", type=int, metavar="S", help="run this one seed (a replay)")
    p.add_argument(
        "--robots",
        default="3-5",
        metavar="MIN-MAX",
        help="robots in the team besides the origin: N or MIN-MAX (3-5)",
    )
    p.add_argument("--jobs", type=int, default=1, metavar="J", help="processes (1)")
    p.add_argument("--trace", action="store_true", help="print every run's trace")
    p.add_argument("--no-shrink", action="store_true", help="do not shrink failing seeds")
    p.add_argument(
        "--plan", type=Path, metavar="FILE", help="replay a plan saved with --save-failures"
    )
    p.add_argument(
        "--save-failures",
        type=Path,
        metavar="DIR",
        help="write each failing seed's shrunken plan to DIR/seed-S.json",
    )
    p.add_argument(
        "--heavy",
        action="store_true",
        help="heavier faults: 4-14 of them over 8-24 s, one-way link cuts, loss up to 40 %%",
    )
    p.add_argument(
        "--inject-fault",
        action="store_true",
        help="add a fault outside the fault model (every execution message is also "
        "delivered to one more robot), to see a failure caught, replayed and shrunk",
    )
    p.set_defaults(handler=sim_test_command)


def parse_robots(text: str) -> tuple[int, int]:
    """``"4"`` -> (4, 4), ``"3-5"`` -> (3, 5); CliError for anything else."""
    lo, sep, hi = text.partition("-")
    try:
        pair = (int(lo), int(hi if sep else lo))
    except ValueError:
        raise CliError(f"--robots: expected N or MIN-MAX (e.g. 3-5), got {text!r}") from None
    if not 1 <= pair[0] <= pair[1] <= 20:
        raise CliError(f"--robots: expected 1 <= MIN <= MAX <= 20, got {text!r}")
    return pair


@dataclass(frozen=True)
class Draw:
    """How seeds become plans (the options a replay command must repeat)."""

    robots: tuple[int, int] = (3, 5)
    inject: bool = False
    heavy: bool = False

    def plan(self, seed: int) -> Plan:
        from btcap.sim.faults.plan import plan_for

        return plan_for(seed, robots=self.robots, inject=self.inject, heavy=self.heavy)

    def replay(self, seed: int) -> str:
        lo, hi = self.robots
        extra = "" if self.robots == (3, 5) else f" --robots {lo}-{hi}"
        extra += " --heavy" if self.heavy else ""
        extra += " --inject-fault" if self.inject else ""
        return f"btcap sim-test --seed {seed}{extra} --trace"


def _check(args: argparse.Namespace) -> Draw:
    if args.seeds < 1:
        raise CliError(f"--seeds: expected a positive number, got {args.seeds}")
    if args.start < 0 or (args.seed is not None and args.seed < 0):
        raise CliError("--start/--seed: expected a seed >= 0")
    if args.jobs < 1:
        raise CliError(f"--jobs: expected a positive number, got {args.jobs}")
    if args.save_failures is not None and not args.save_failures.is_dir():
        raise CliError(f"--save-failures: {args.save_failures} is not a folder")
    return Draw(parse_robots(args.robots), args.inject_fault, args.heavy)


def sim_test_command(args: argparse.Namespace) -> int:
    draw = _check(args)
    if args.log_level == "warning":  # the faults make warnings routine: errors only
        configure_logging("error", json=args.log_json)
    started = time.perf_counter()
    from btcap.sim.faults.plan import load_plan
    from btcap.sim.faults.run import run_plan

    if args.plan is not None:
        try:
            plan = load_plan(args.plan)
        except ValueError as exc:
            raise CliError(f"--plan: {exc}") from None
        return _report_all([_show(run_plan(plan), args, draw)], started)
    if args.seed is not None:
        return _report_all([_show(run_plan(draw.plan(args.seed)), args, draw)], started)
    seeds = range(args.start, args.start + args.seeds)
    if args.jobs == 1:
        results = [_show(run_plan(draw.plan(s)), args, draw) for s in seeds]
    else:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs) as pool:
            outcomes = pool.map(_run_seed, seeds, [draw] * len(seeds), chunksize=8)
            results = [_show(o, args, draw) for o in outcomes]
    return _report_all(results, started)


def _run_seed(seed: int, draw: Draw) -> Outcome:
    from btcap.sim.faults.run import run_plan

    return run_plan(draw.plan(seed))


def _show(outcome: Outcome, args: argparse.Namespace, draw: Draw) -> Outcome:
    seed = outcome.plan.seed
    if args.trace:
        print("\n".join(outcome.trace))
    if outcome.ok:
        return outcome
    print(f"seed {seed}: FAILED: {outcome.violations[0]}")
    print(f"  replay: {draw.replay(seed)}")
    if args.no_shrink:
        return outcome
    from btcap.sim.faults.plan import save_plan
    from btcap.sim.faults.shrink import shrink

    small = shrink(outcome)
    print(
        f"  shrunk from {len(outcome.plan.faults)} to {len(small.plan.faults)} faults: "
        f"{small.violations[0]}"
    )
    for line in small.trace:
        print(f"  | {line}")
    if args.save_failures is not None:
        path = args.save_failures / f"seed-{seed}.json"
        save_plan(small.plan, path)
        print(f"  shrunken plan: btcap sim-test --plan {path} --trace")
    return outcome


def _report_all(results: list[Outcome], started: float) -> int:
    failed = [o.plan.seed for o in results if not o.ok]
    simulated = sum(o.end_s for o in results)
    false_failures = sum(o.failures for o in results)
    doubles = sum(o.double_ticks for o in results)
    print(
        f"{len(results)} seeds, {len(failed)} failed"
        + (f" ({', '.join(map(str, failed[:20]))})" if failed else "")
        + f"; {simulated / 3600:.2f} simulated hours, {false_failures} failures declared, "
        f"{doubles} ticks of a task on two robots at once, "
        f"in {time.perf_counter() - started:.1f} s"
    )
    return 1 if failed else 0
