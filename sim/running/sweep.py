"""``btcap sweep``: one scenario over many seeds in the deterministic fast mode, per
allocation configuration, as a table of spreads, ``sweep.json`` and a box plot.

Every run is :func:`~btcap.sim.running.runner.run_fast` on a virtual clock, so a seed's result
depends on nothing but the scenario: runs are spread over worker processes and
``sweep.json`` is the same for the same arguments, however many jobs ran them.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import msgspec

from btcap.cli import CliError

if TYPE_CHECKING:  # the simulation is imported when a sweep starts: --help stays fast
    from concurrent.futures import Future

    from rich.table import Table

    from btcap.sim.mission.scenario import Scenario
    from btcap.sim.running.metrics import MissionResult

__all__ = [
    "ConfigResult",
    "Configuration",
    "RunFigures",
    "Spread",
    "SweepResult",
    "add_parser",
    "configurations",
    "plot_sweep",
    "run_sweep",
    "sweep_command",
    "sweep_table",
]


class RunFigures(msgspec.Struct):
    """What one seed's run contributes to a sweep. ``idle_s``: mean over the robots that
    took part of the time they were present but not working."""

    seed: int
    completed: bool
    mission_time_s: float
    idle_s: float
    distance_m: float
    auctions: int
    reassigned: int
    moved: int

    @classmethod
    def of(cls, seed: int, r: MissionResult) -> RunFigures:
        present = [st for st in r.robots.values() if st.present_s > 0]
        idle = [max(0.0, st.present_s - st.busy_s) for st in present]
        return cls(
            seed=seed,
            completed=r.completed,
            mission_time_s=r.mission_time_s,
            idle_s=round(statistics.fmean(idle), 3) if idle else 0.0,
            distance_m=round(sum(st.distance_m for st in r.robots.values()), 2),
            auctions=r.auctions,
            reassigned=r.reassigned,
            moved=r.moved,
        )


#: The figures summarised per configuration: field of :class:`RunFigures`, table label,
#: decimals of the mean and spread.
METRICS: tuple[tuple[str, str, int], ...] = (
    ("mission_time_s", "mission time [s]", 0),
    ("idle_s", "idle time [s/robot]", 0),
    ("distance_m", "distance [m]", 0),
    ("auctions", "auctions", 1),
    ("reassigned", "re-assigned", 1),
    ("moved", "moved (cheaper)", 1),
)


class Spread(msgspec.Struct):
    """Over the seeds; ``std`` is the sample standard deviation (None for one seed)."""

    mean: float
    std: float | None
    min: float
    max: float

    @classmethod
    def of(cls, values: Sequence[float]) -> Spread:
        std = statistics.stdev(values) if len(values) > 1 else None
        return cls(
            round(statistics.fmean(values), 3),
            None if std is None else round(std, 3),
            min(values),
            max(values),
        )


class ConfigResult(msgspec.Struct):
    name: str
    strategy: str | None
    reevaluate_s: float | None
    runs: list[RunFigures]
    stats: dict[str, Spread]


class SweepResult(msgspec.Struct):
    scenario: str
    seeds: list[int]
    configurations: list[ConfigResult]

    def to_json(self) -> bytes:
        return msgspec.json.format(msgspec.json.encode(self), indent=2) + b"\n"


@dataclass(frozen=True)
class Configuration:
    """A scenario with one allocation policy; its seed is replaced per run."""

    name: str
    scenario: Scenario

    @property
    def strategy(self) -> str | None:
        value = getattr(self.scenario.allocation, "strategy", None)
        return value if isinstance(value, str) else None


def _has_strategy() -> bool:
    from btcap.sim.mission.scenario import Allocation

    return any(f.name == "strategy" for f in msgspec.structs.fields(Allocation))


def configurations(
    scenario: Scenario, strategies: Sequence[str] = (), *, reevaluate: bool = True
) -> list[Configuration]:
    """One configuration per strategy (none given: the scenario's own), with running
    work re-evaluated as the scenario says or, with ``reevaluate=False``, never.

    Raises :class:`ScenarioError` naming the strategy that the scenario does not accept.
    """
    from btcap.sim.mission.scenario import Allocation, ScenarioError, check_scenario

    base = scenario
    if not reevaluate:
        base = msgspec.structs.replace(
            base, allocation=msgspec.structs.replace(base.allocation, reevaluate_s=None)
        )
    if strategies and not _has_strategy():
        raise ScenarioError(
            "this version of btcap has no allocation strategy to choose "
            f"(allocation accepts: {', '.join(f.name for f in msgspec.structs.fields(Allocation))})"
        )
    variants: list[Scenario] = []
    for name in dict.fromkeys(strategies):
        alloc = msgspec.structs.replace(base.allocation, strategy=name)
        variants.append(check_scenario(msgspec.structs.replace(base, allocation=alloc)))
    if not variants:
        variants.append(base)
    out = []
    for s in variants:
        every = s.allocation.reevaluate_s
        policy = "no re-eval" if every is None else f"re-eval {every:g} s"
        strategy = getattr(s.allocation, "strategy", None)
        out.append(Configuration(f"{strategy}, {policy}" if strategy else policy, s))
    return out


def _run_seed(scenario: Scenario) -> dict[str, Any]:
    """One run, in a worker process or in this one; builtins cross the process boundary."""
    import asyncio

    from btcap.sim.running.runner import run_fast

    result: dict[str, Any] = msgspec.to_builtins(asyncio.run(run_fast(scenario)))
    return result


def _worker_init(log_level: str, log_json: bool) -> None:
    from btcap.actors import configure_logging

    # Ctrl-C is the parent's to handle: it cancels what has not started and waits.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    configure_logging(log_level, json=log_json)


def _available_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _results(
    runs: list[Scenario], jobs: int, log: tuple[str, bool]
) -> Iterator[tuple[int, dict[str, Any]]]:
    """(index, result) of every run as it finishes: in this process for one job."""
    if jobs == 1 or len(runs) == 1:
        for i, s in enumerate(runs):
            yield i, _run_seed(s)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(
        max_workers=min(jobs, len(runs)),
        mp_context=multiprocessing.get_context("spawn"),  # no fork of a threaded parent
        initializer=_worker_init,
        initargs=log,
    )
    try:
        futures: dict[Future[dict[str, Any]], int] = {
            pool.submit(_run_seed, s): i for i, s in enumerate(runs)
        }
        for f in as_completed(futures):
            yield futures[f], f.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def run_sweep(
    configs: Sequence[Configuration],
    seeds: Sequence[int],
    *,
    jobs: int = 1,
    on_done: Callable[[], None] | None = None,
    log: tuple[str, bool] = ("warning", False),
) -> SweepResult:
    """Run every configuration for every seed on up to ``jobs`` processes; ``log`` is the
    level and JSON flag the worker processes log with."""
    from btcap.sim.running.metrics import MissionResult

    if jobs < 1 or not seeds or not configs:
        raise ValueError("run_sweep: expected jobs >= 1, seeds and configurations")
    runs = [msgspec.structs.replace(c.scenario, seed=seed) for c in configs for seed in seeds]
    figures: list[RunFigures | None] = [None] * len(runs)
    for i, builtins in _results(runs, jobs, log):
        figures[i] = RunFigures.of(runs[i].seed, msgspec.convert(builtins, MissionResult))
        if on_done is not None:
            on_done()
    out = []
    for k, c in enumerate(configs):
        mine = [f for f in figures[k * len(seeds) : (k + 1) * len(seeds)] if f is not None]
        stats = {key: Spread.of([getattr(f, key) for f in mine]) for key, _, _ in METRICS}
        out.append(
            ConfigResult(c.name, c.strategy, c.scenario.allocation.reevaluate_s, mine, stats)
        )
    return SweepResult(configs[0].scenario.name, list(seeds), out)


def sweep_table(result: SweepResult) -> Table:
    from rich.table import Table
    from rich.text import Text

    seeds = result.seeds
    span = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {seeds[0]}..{seeds[-1]}"
    t = Table(title=f"{result.scenario}: {span}, fast mode", caption="std: sample std over seeds")
    t.add_column("configuration")
    t.add_column("")
    for col in ("mean", "std", "min", "max"):
        t.add_column(col, justify="right")
    for c in result.configurations:
        done = sum(r.completed for r in c.runs)
        label = f"{c.name}\n{done}/{len(c.runs)} completed"
        for n, (key, name, decimals) in enumerate(METRICS):
            st = c.stats[key]
            std = "-" if st.std is None else f"{st.std:.{decimals}f}"
            t.add_row(
                label if n == 0 else "",
                Text(name),  # not markup: "[s]" would be a style
                f"{st.mean:.{decimals}f}",
                std,
                f"{st.min:.0f}",
                f"{st.max:.0f}",
                end_section=n == len(METRICS) - 1,
            )
    return t


def plot_sweep(result: SweepResult, path: str | Path) -> Path:
    """A box plot of mission time per configuration, every seed as a dot (a red cross if
    its mission did not complete)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    configs = result.configurations
    fig, ax = plt.subplots(figsize=(3.5 + 2.0 * len(configs), 4.5), dpi=110)
    ax.boxplot(
        [[r.mission_time_s for r in c.runs] for c in configs],
        widths=0.5,
        showfliers=False,
        medianprops={"color": "#4c72b0"},
    )
    ax.set_xticks(range(1, len(configs) + 1), [c.name for c in configs])
    for x, c in enumerate(configs, start=1):
        n = len(c.runs)
        for j, r in enumerate(c.runs):
            dx = 0.3 * (j / (n - 1) - 0.5) if n > 1 else 0.0  # spread, not random jitter
            style = ("o", "#333333") if r.completed else ("x", "#d62728")
            ax.plot([x + dx], [r.mission_time_s], style[0], color=style[1], ms=5, alpha=0.8)
    ax.set_ylabel("mission time [s]")
    seeds = result.seeds
    ax.set_title(f"{result.scenario}: mission time over {len(seeds)} seeds (fast mode)")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out)
    plt.close(fig)
    return out


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a scenario over many seeds in the fast mode and compare the spread",
        description="Run a scenario for seeds 1..N on virtual time (the scenario's own seed is "
        "replaced), per allocation strategy, and print mean, std, min and max of the mission "
        "figures; writes sweep.json and sweep.png into an output folder.",
    )
    p.add_argument("scenario", help="a scenario file or a built-in name")
    p.add_argument("--seeds", type=int, required=True, metavar="N", help="run seeds 1..N")
    p.add_argument(
        "--strategy",
        action="extend",
        nargs="+",
        default=[],
        metavar="NAME",
        help="allocation strategies to compare (default: the scenario's own)",
    )
    p.add_argument(
        "--no-reevaluate",
        action="store_true",
        help="never re-evaluate running work (the baseline of allocation that keeps adapting)",
    )
    p.add_argument("--out", type=Path, help="output folder (default: a new folder under runs/)")
    p.add_argument(
        "--jobs",
        type=int,
        metavar="J",
        help="worker processes (default: the CPUs available, at most one per run)",
    )
    p.set_defaults(handler=sweep_command)


def _out_dir(args: argparse.Namespace, name: str) -> Path:
    if args.out is not None:
        out = Path(args.out)
    else:
        out = Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-sweep-{name}"
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out}: exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"--out {out}: cannot create ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise CliError(f"--out {out}: not writable")
    return out


def sweep_command(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.progress import Progress

    from btcap.sim.mission.scenario import ScenarioError, resolve_scenario

    console = Console()
    if args.seeds < 1:
        raise CliError(f"--seeds: expected a number of seeds >= 1, got {args.seeds}")
    if args.jobs is not None and args.jobs < 1:
        raise CliError(f"--jobs: expected >= 1, got {args.jobs}")
    try:
        scenario = resolve_scenario(args.scenario)
        configs = configurations(scenario, args.strategy, reevaluate=not args.no_reevaluate)
    except ScenarioError as exc:
        raise CliError(f"--strategy: {exc}" if args.strategy else str(exc)) from None
    out = _out_dir(args, scenario.name)
    seeds = list(range(1, args.seeds + 1))
    total = len(seeds) * len(configs)
    jobs = min(args.jobs or _available_cpus(), total)
    log = (getattr(args, "log_level", "warning"), bool(getattr(args, "log_json", False)))
    console.print(
        f"sweeping [bold]{scenario.name}[/bold]: {len(configs)} configuration(s) x "
        f"{len(seeds)} seeds on {jobs} process(es) ..."
    )
    wall = time.perf_counter()
    with Progress(console=console, transient=True, disable=not console.is_terminal) as bar:
        task = bar.add_task("runs", total=total)
        result = run_sweep(configs, seeds, jobs=jobs, on_done=lambda: bar.advance(task), log=log)
    wall = time.perf_counter() - wall
    try:
        (out / "sweep.json").write_bytes(result.to_json())
        plot_sweep(result, out / "sweep.png")
    except OSError as exc:
        raise CliError(f"cannot write results to {out}: {exc.strerror or exc}") from None
    console.print(sweep_table(result))
    simulated = sum(r.mission_time_s for c in result.configurations for r in c.runs)
    console.print(
        f"{total} runs in {wall:.1f} s wall ({simulated / wall:.0f}x simulated time); "
        f"results written to [bold]{out}[/bold] (sweep.json, sweep.png)"
    )
    return 0 if all(r.completed for c in result.configurations for r in c.runs) else 1
