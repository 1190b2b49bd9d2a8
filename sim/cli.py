"""``btcap run``: the reference mission, with a live display, a summary, a plot and JSON."""

from __future__ import annotations

import argparse
import functools
import json
import math
import signal
import tempfile
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING

from btcap.cli import CliError
from btcap.cli.monitor import add_monitor_option
from btcap.sim.faults import cli as simtestcli
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.running.runview import progress_line, progress_view, summary_table
from btcap.sim.running.stopper import STOPPED_BY, Stopper

if TYPE_CHECKING:  # the simulation is imported when a run starts: --help stays fast
    from rich.console import Console

    from btcap.monitor import Monitor
    from btcap.sim.mission.scenario import Scenario
    from btcap.sim.running.metrics import MissionResult
    from btcap.sim.running.runner import Progress

__all__ = ["add_parser", "run_command"]

DEFAULT = "full-team"

#: Mission seconds between two progress lines when stdout is not a terminal.
LINE_EVERY_S = 100.0


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "run",
        help="run the find-and-decontaminate mission (default scenario: full-team)",
        description="Run a simulated mission scenario and write a summary, a timeline plot "
        "and a JSON result into an output folder.",
    )
    p.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO",
        help=f"a scenario file or a built-in name ({', '.join(builtin_scenarios())}; "
        f"default {DEFAULT}); several only with --compare",
    )
    p.add_argument(
        "--out",
        type=Path,
        help="output folder, checked before the run (default: a new folder under runs/)",
    )
    p.add_argument(
        "--compare",
        action="store_true",
        help="run the given scenarios (default: every built-in one) one after the other, each "
        "into OUT/NAME, and draw them side by side in OUT/compare.png",
    )
    p.add_argument(
        "--distributed",
        action="store_true",
        help="every robot in its own OS process, talking ZeroMQ over tcp loopback, as on "
        "separate hosts; the simulation and the mission tree stay in this process (wall "
        "clock at the scenario's speed-up, so not with --fast)",
    )
    p.add_argument(
        "--ros2",
        action="store_true",
        help="every robot reached through ROS 2 interfaces the simulation serves in its "
        "namespace, with the scenario's `ros:` block (a file with one runs so without this "
        "flag) or its defaults (`make ros-sim`, then .venv-ros/bin/python -m btcap)",
    )
    p.add_argument(
        "--ros1",
        action="store_true",
        help="every robot reached through ROS 1 as in the paper: a move_base action server "
        "per robot and the simulation's operations as ROS services, on the scenario's "
        "`ros.master_uri` or a rosmaster of the run's own on loopback (`backend: ros1` in a "
        "`ros:` block does the same; `make ros1`, then .venv-ros1/bin/python -m btcap)",
    )
    p.add_argument("--speedup", type=float, help="override the scenario's clock speed-up")
    p.add_argument(
        "--robots",
        type=int,
        metavar="N",
        help="grow the team to N robots: the scenario's robots' models in turn, named "
        "MODEL2, MODEL3, ... (full-team --robots 200: 67 huskies, 67 spots, 66 bebops); "
        "the mission still runs at most 1 + object_workers capabilities at once, so "
        "robots beyond that wait unless --object-workers grows it too",
    )
    p.add_argument(
        "--object-workers",
        type=int,
        metavar="K",
        help="identify-and-decontaminate loops the mission tree runs at once (the "
        "scenario's object_workers: 2 in the built-in ones)",
    )
    p.add_argument(
        "--mission",
        choices=("paper", "pool"),
        help="the mission tree: paper (the paper's loops; the built-in scenarios' choice) or "
        "pool (a lane per goal and per object: identify, then carry)",
    )
    p.add_argument(
        "--fast",
        action="store_true",
        help="virtual time that jumps whenever every robot waits: as fast as the computation "
        "allows, and the same scenario and seed give the same result",
    )
    p.add_argument(
        "--rebid-on-join",
        type=float,
        metavar="FRACTION",
        help="move running work to a joining robot that bids this fraction cheaper",
    )
    p.add_argument(
        "--queue-after-current",
        action="store_true",
        help="busy robots bid for one more task, to start after their current one",
    )
    p.add_argument("--quiet", action="store_true", help="no live display nor progress lines")
    add_monitor_option(p)
    p.add_argument(
        "--record",
        type=Path,
        metavar="FILE",
        help="record trees, runs, auctions and team events for btcap replay, as MCAP if "
        "FILE ends .mcap, else JSON Lines (default: monitor.jsonl in the output folder)",
    )
    p.add_argument("--no-record", action="store_true", help="write no recording")
    p.add_argument(
        "--btlog",
        type=Path,
        metavar="OUT.btlog",
        help="log the mission tree's run as BehaviorTree.CPP's file logger does, for Groot2 "
        "to replay (with --compare, one file per scenario: OUT-NAME.btlog)",
    )
    p.set_defaults(handler=run_command)
    simtestcli.add_parser(sub)


def _out_dir(args: argparse.Namespace, name: str) -> Path:
    if args.out is not None:
        return Path(args.out)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{stamp}-{name}"


def _check_out(out: Path) -> None:
    """Refuse an output folder the results could not be written to, before the run."""
    if out.exists() and not out.is_dir():
        raise CliError(f"output folder {out}: exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise CliError(f"output folder {out}: cannot write there: {exc.strerror or exc}") from None


def _write(result: MissionResult, out: Path) -> None:
    from btcap.sim.running.plots import plot_timeline

    out.mkdir(parents=True, exist_ok=True)
    (out / "result.json").write_bytes(result.to_json())
    plot_timeline(result, out / "timeline.png")


async def _run_and_write(
    run: Callable[[Monitor | None], Awaitable[MissionResult]],
    folder: Path,
    out: Path,
    monitors: list[Monitor | None],
    monitor: Monitor | None,
) -> MissionResult:
    """Run, then write the results while the monitor still serves how the run ended
    (``monitor`` goes into ``monitors``: the caller asks it how its recording went)."""
    monitors.append(monitor)
    result = await run(monitor)
    try:
        _write(result, folder)
    except OSError as exc:
        raise CliError(f"cannot write results to {out}: {exc.strerror or exc}") from None
    return result


async def _run_one(
    s: Scenario,
    console: Console,
    quiet: bool,
    distributed: bool,
    fast: bool,
    stopper: Stopper,
    monitor: Monitor | None = None,
    *,
    ros2: bool = False,
    btlog: Path | None = None,
    ros1: bool = False,
) -> MissionResult:
    from rich.live import Live

    from btcap.sim.running.runner import run_fast, run_scenario

    runner: Callable[..., Awaitable[MissionResult]] = run_fast if fast else run_scenario
    if distributed:
        from btcap.sim.running.distributed import run_distributed

        runner = run_distributed
    if ros2:
        runner = functools.partial(run_scenario, ros2=True)
    if ros1:
        runner = functools.partial(run_scenario, ros1=True)
    if monitor is not None:
        runner = functools.partial(runner, monitor=monitor)
    if btlog is not None:
        runner = functools.partial(runner, btlog=btlog)
    stop = stopper.event()
    if quiet:
        return await runner(s, stop=stop)
    if not console.is_terminal:  # a log: a line every LINE_EVERY_S of mission time

        def line(p: Progress) -> None:
            console.print(progress_line(p, s.name), markup=False, highlight=False, soft_wrap=True)

        every = {"progress_every_s": LINE_EVERY_S, "progress_clock": "mission"}
        return await runner(s, on_progress=line, stop=stop, **every)
    with Live(console=console, refresh_per_second=8, transient=True) as live:

        def show(p: Progress) -> None:
            live.update(progress_view(p, s.name))

        return await runner(s, on_progress=show, stop=stop)


def run_command(args: argparse.Namespace) -> int:
    import asyncio

    import msgspec
    from rich.console import Console

    from btcap.cli.monitor import monitored
    from btcap.sim.mission.bound import scenario_bound
    from btcap.sim.mission.scenario import (
        ScenarioError,
        check_ros_names,
        grow_team,
        resolve_scenario,
        run_metadata,
    )
    from btcap.sim.running.metrics import idle_robots_note
    from btcap.sim.running.plots import plot_comparison

    console = Console()
    if args.compare:
        names = args.scenarios or list(builtin_scenarios())
    elif len(args.scenarios) > 1:
        raise CliError("run takes one scenario; add --compare to run several side by side")
    else:
        names = args.scenarios or [DEFAULT]
    if args.speedup is not None and not (math.isfinite(args.speedup) and args.speedup > 0):
        raise CliError(f"--speedup: expected a number > 0, got {args.speedup:g}")
    try:
        scenarios = [resolve_scenario(n) for n in names]
    except ScenarioError as exc:  # a usage problem: the message names file and field
        raise CliError(str(exc)) from None
    if args.fast and (args.distributed or args.speedup is not None):
        raise CliError(
            "--fast runs in one process on virtual time: not with --distributed or --speedup"
        )
    for s in scenarios:
        if args.ros1 and args.ros2:
            raise CliError("--ros1 and --ros2: one ROS version at a time")
        if args.ros1 or args.ros2 or s.ros is not None:
            import msgspec

            from btcap.sim.mission.scenariofile import ScenarioRos
            from btcap.sim.ros1 import ros1_refused, wants_ros1
            from btcap.sim.ros2 import ros2_refused

            one = wants_ros1(args.ros1, args.ros2, s.ros)
            backend = "ros1" if one else "ros2"  # the ROS the run goes over, for its errors
            block = msgspec.structs.replace(s.ros or ScenarioRos(), backend=backend)
            try:
                check_ros_names(s, block)
            except ScenarioError as exc:
                raise CliError(str(exc)) from None
            refused = ros1_refused if one else ros2_refused
            why = refused(fast=args.fast, distributed=args.distributed)
            if why is not None:
                raise CliError(why if args.ros1 or args.ros2 else f"{s.source}: ros: {why}")
    if args.btlog is not None and args.btlog.suffix != ".btlog":
        raise CliError(f"--btlog {args.btlog}: a tree log for Groot2 must be named *.btlog")
    margin = args.rebid_on_join
    if margin is not None and not 0 < margin < 1:
        raise CliError(f"--rebid-on-join: expected a fraction within (0, 1), got {margin:g}")
    for s in scenarios:
        if args.robots is not None:
            try:
                grow_team(s, args.robots)
            except ValueError as exc:
                raise CliError(f"--robots: {exc}") from None
        if args.object_workers is not None:
            if not 1 <= args.object_workers <= 1000:
                raise CliError(f"--object-workers: expected 1 to 1000, got {args.object_workers}")
            s.object_workers = args.object_workers
        if args.mission is not None:
            s.mission = args.mission
        if args.speedup is not None:
            s.speedup = args.speedup
        if margin is not None:
            s.allocation = msgspec.structs.replace(s.allocation, rebid_on_join=margin)
        if args.queue_after_current:
            s.allocation = msgspec.structs.replace(s.allocation, queue_after_current=True)
    if args.compare:
        named = [s.name for s in scenarios]
        twice = sorted({n for n in named if named.count(n) > 1})
        if twice:
            raise CliError(
                f"--compare: two scenarios named {', '.join(twice)}: each one's results go "
                "into a folder of its name"
            )
    out = _out_dir(args, "compare" if args.compare else scenarios[0].name)
    _check_out(out)
    if args.compare:
        console.print(f"comparing {len(scenarios)} scenarios: {', '.join(named)}", markup=False)
    results: list[MissionResult] = []
    with Stopper() as stopper:
        for s in scenarios:
            pace = "virtual time" if args.fast else f"speed-up {s.speedup:g}x"
            if args.ros1 or args.ros2 or s.ros is not None:
                from btcap.sim.ros1 import wants_ros1

                pace += f", robots through ROS {2 - wants_ros1(args.ros1, args.ros2, s.ros)}"
            console.print(f"running [bold]{s.name}[/bold] ({pace}) ...")
            folder = out / s.name if args.compare else out
            record = args.record or folder / "monitor.jsonl"
            if args.compare and args.record is not None:
                suffix = args.record.suffix or ".jsonl"
                record = args.record.with_name(f"{args.record.stem}-{s.name}{suffix}")
            flags = (args.quiet, args.distributed, args.fast)
            btlog = args.btlog
            if args.compare and btlog is not None:
                btlog = btlog.with_name(f"{btlog.stem}-{s.name}.btlog")
            ros = {"ros2": args.ros2, "ros1": args.ros1}
            run = functools.partial(_run_one, s, console, *flags, stopper, **ros, btlog=btlog)
            keep = None if args.no_record else record
            monitors: list[Monitor | None] = []  # which recorded, and how that went
            write = functools.partial(_run_and_write, run, folder, out, monitors)
            started = time.perf_counter()
            meta = run_metadata(s, fast=args.fast, distributed=args.distributed)
            result = asyncio.run(
                monitored(args.monitor, keep, s.name, write, meta, foxglove=args.foxglove)
            )
            wall = time.perf_counter() - started
            bound = scenario_bound(s).seconds
            console.print(
                f"{s.name}: {len(s.robots)} robots, {s.mission} mission, "
                f"{result.mission_time_s:.0f} s of mission (lower bound {bound:.0f} s: "
                f"{result.mission_time_s / bound if bound else math.inf:.2f}x) in {wall:.1f} s "
                "of wall time",
                markup=False,
            )
            idle = idle_robots_note(result, s.object_workers) if s.mission == "paper" else None
            if idle is not None:
                console.print(idle, markup=False, soft_wrap=True)
            failed = next((m.recording_failed for m in monitors if m is not None), None)
            if keep is not None and failed is not None:  # said by the log too, long ago
                console.print(
                    f"recording {keep} stopped before the end: {failed}; it holds what came "
                    f"before (btcap replay {keep} reads up to there)",
                    markup=False,
                    soft_wrap=True,
                )
            elif keep is not None:
                console.print(f"recorded {keep} (btcap replay {keep})", markup=False)
            if btlog is not None:
                console.print(f"wrote {btlog} (open it in Groot2)", markup=False)
            results.append(result)
            if stopper.signum is not None:
                console.print(f"interrupted by {signal.Signals(stopper.signum).name}")
                break
    console.print(summary_table(results))
    written = "result.json, timeline.png"
    if args.compare:
        plot_comparison(results, out / "compare.png")
        written = "NAME/result.json, NAME/timeline.png, compare.json, compare.png"
        (out / "compare.json").write_text(
            json.dumps(
                {
                    r.scenario: {"completed": r.completed, "mission_time_s": r.mission_time_s}
                    for r in results
                },
                indent=2,
            )
            + "\n"
        )
    console.print(f"results written to [bold]{out}[/bold] ({written})")
    if stopper.signum is not None:
        return STOPPED_BY[signal.Signals(stopper.signum)]
    return 0 if all(r.completed for r in results) else 1
