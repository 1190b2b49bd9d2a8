"""``btcap agent``, ``btcap team status`` and ``btcap mission run``: one robot per host.

Each reads an agent configuration file (:mod:`btcap.team.deployment.agentconfig`); a bad file exits
with status 2 and a message naming the file and the field. SIGINT and SIGTERM end each
command cleanly, with one line and exit status 130 or 143 (128 + the signal's number):
the robot says goodbye, so the team re-assigns its work at once.
"""

from __future__ import annotations

import argparse
import functools
import signal
import sys
from collections.abc import Awaitable, Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from btcap.bt.state import TreeError
from btcap.cli import CliError, Stopped
from btcap.cli.monitor import add_monitor_option

if TYPE_CHECKING:  # the rest is imported by the command that runs: --help stays fast
    from btcap.bt.registry import NodeRegistry
    from btcap.cli.teamwords import Joining
    from btcap.team.deployment.agentconfig import RobotConfig
    from btcap.team.deployment.deploy import MemberView, MissionReport
    from btcap.team.runtime.agent import Agent

__all__ = ["add_parser"]

T = TypeVar("T")
_STOP = (signal.SIGINT, signal.SIGTERM)


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``agent``, ``team status`` and ``mission run``."""
    p = subparsers.add_parser(
        "agent",
        help="run one robot from its configuration file until SIGINT or SIGTERM",
        description="Run one robot in the foreground; it leaves the team cleanly when "
        "stopped with SIGINT or SIGTERM. Prints one line once it listens.",
    )
    p.add_argument("config", metavar="CONFIG", type=Path)
    p.add_argument(
        "--insecure",
        action="store_true",
        help="allow a bind reachable from other hosts without keys",
    )
    add_monitor_option(p)
    _record_option(p, "this robot's host tree and runs, the auctions it holds and the "
                   "team's joins and failures as it sees them")  # fmt: skip
    p.add_argument(
        "--until-stdin-closes",
        action="store_true",
        help="also leave when standard input closes (for a supervisor holding a pipe to it)",
    )
    p.set_defaults(handler=_agent)

    team = subparsers.add_parser("team", help="look at a running team")
    team_cmds = team.add_subparsers(dest="team_command", metavar="SUBCOMMAND")
    p = team_cmds.add_parser(
        "status",
        help="ask the team (without joining it) for its members, capabilities and runs, "
        "and the robots that failed or left lately (when and why)",
        description="Ask the seeds, then every member they name, how they see the team; "
        "print the members, what each offers and runs, and how fresh its heartbeat is, "
        "and the robots that failed or left lately. "
        "It observes as CONFIG's robot plus a tag (e.g. operator+status-1a2b3c), with "
        "that robot's key: it never joins, so it can run beside that robot's agent or "
        "mission. Exit status 1 if a seed or a member did not answer within --wait.",
    )
    _join_options(p, default_wait=3.0)
    p.set_defaults(handler=_status)

    mission = subparsers.add_parser("mission", help="run missions on a running team")
    mission_cmds = mission.add_subparsers(dest="mission_command", metavar="SUBCOMMAND")
    p = mission_cmds.add_parser(
        "run",
        help="join the team as an operator and tick a mission tree to its end",
        description="Exit status 0 if the mission succeeded, 1 if it failed or timed out, "
        "or if the config names seeds and none answered within --wait (then the mission "
        "is not started, and the line says which seeds and what to check).",
    )
    p.add_argument("tree", metavar="TREE", type=Path)
    _join_options(p, default_wait=10.0)
    p.add_argument("--timeout", type=float, default=None, help="give up after this many seconds")
    add_monitor_option(p)
    _record_option(p, "the mission's runs, auctions and the team's joins and failures")
    p.set_defaults(handler=_mission)


def _record_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--record",
        type=Path,
        metavar="FILE",
        help=f"record {what} for btcap replay or a script: MCAP for Foxglove if FILE ends "
        ".mcap, else JSON Lines",
    )


def _join_options(p: argparse.ArgumentParser, *, default_wait: float) -> None:
    p.add_argument("--config", required=True, type=Path, help="agent configuration file")
    p.add_argument(
        "--wait",
        type=float,
        default=default_wait,
        help=f"seconds to wait for the seeds to answer (default {default_wait})",
    )
    p.add_argument(
        "--as",
        dest="robot",
        default=None,
        help="robot name to join as (team status: to observe for; with keys, its key's)",
    )


def _config(path: Path) -> RobotConfig:
    from btcap.team.deployment.agentconfig import AgentConfigError, load_agent_file

    try:
        return load_agent_file(path)
    except AgentConfigError as exc:
        raise CliError(str(exc)) from None


def _registry(args: argparse.Namespace) -> NodeRegistry:
    from btcap.bt.registry import default_registry

    return default_registry(plugins=not args.no_plugins)


def _until_stopped(
    work: Callable[[], Awaitable[T]],
    args: argparse.Namespace,
    doing: str | Callable[[], str] = "leaving the team",
) -> T:
    """Run ``work`` in a fresh event loop. SIGINT or SIGTERM cancel it, saying so on one
    line (unless ``--log-level error``: a supervisor that stops its robots wants no word
    from each) what it does then (``doing``, or what it returns), and raise
    :class:`Stopped` once it has wound down."""
    import anyio

    from btcap.actors.loops import loop_factory
    from btcap.team.deployment.agentconfig import AgentConfigError
    from btcap.transports.zmq_claims import NameTaken

    result: list[T] = []
    stopped_by: list[int] = []

    async def main() -> None:
        with anyio.open_signal_receiver(*_STOP) as signals:
            async with anyio.create_task_group() as tg:

                async def run() -> None:
                    result.append(await work())
                    tg.cancel_scope.cancel()

                tg.start_soon(run)
                async for sig in signals:
                    stopped_by.append(sig)
                    if args.log_level != "error":
                        what = doing if isinstance(doing, str) else doing()
                        print(f"btcap: {signal.Signals(sig).name}, {what}", file=sys.stderr)
                    tg.cancel_scope.cancel()
                    break

    try:
        # uvloop when installed (see actors/loops.py); a bad BTCAP_LOOP is a CliError.
        factory = loop_factory()
    except ValueError as exc:
        raise CliError(str(exc)) from None
    try:
        try:
            anyio.run(main, backend_options={"loop_factory": factory})
        except BaseExceptionGroup as group:
            leaf: BaseException = group
            while isinstance(leaf, BaseExceptionGroup) and len(leaf.exceptions) == 1:
                leaf = leaf.exceptions[0]  # one failure: raise it as it is
            raise leaf from None
    except AgentConfigError as exc:  # found once joining: bad keys, a bind refused
        raise CliError(str(exc)) from None
    except NameTaken as exc:  # another live process has this robot's name
        raise CliError(str(exc), code=1) from None
    if not result:
        raise Stopped(stopped_by[0])
    return result[0]


async def _monitor_imports(
    wanted: bool, *, serve: bool, foxglove: bool = False, mcap: bool = False
) -> None:
    """Import the monitor (and its web server if it will ``serve``, the Foxglove SDK's
    server or MCAP writer if it will serve ``foxglove`` or record ``mcap``) in a worker
    thread before the robot joins: it opens once the agent has (it needs the agent), and
    its imports (aiohttp: a third of a second) would hold a member's event loop."""
    if not wanted:
        return
    import importlib

    import anyio

    names = ["btcap.monitor.monitor", *(["btcap.monitor.server"] if serve else [])]
    names += ["btcap.monitor.foxlive"] if foxglove else []
    for name in names + (["btcap.monitor.mcaprecord"] if mcap else []):
        await anyio.to_thread.run_sync(importlib.import_module, name)


# -- btcap agent -------------------------------------------------------------------------
def _agent(args: argparse.Namespace) -> int:
    import anyio

    from btcap.cli.monitor import serving
    from btcap.cli.teamwords import Joining
    from btcap.team.deployment.deploy import open_agent
    from btcap.team.deployment.spawn import listening
    from btcap.team.deployment.supervised import stdin_closed, watchable

    config = _config(args.config)
    registry = _registry(args)
    joining = Joining(config.seeds)
    if args.insecure and config.keys is None:
        print(
            f"btcap: warning: --insecure: {config.robot} speaks to anyone who can reach "
            f"{config.spec.network.bind}, unencrypted and unauthenticated",
            file=sys.stderr,
            flush=True,
        )

    async def serve() -> None:
        fox = args.foxglove is not None
        wanted = args.monitor is not None or args.record is not None or fox
        mcap = args.record is not None and args.record.suffix.lower() == ".mcap"
        await _monitor_imports(wanted, serve=args.monitor is not None, foxglove=fox, mcap=mcap)
        meta = {"robot": config.robot, "config": str(args.config)}
        async with (
            open_agent(config, registry, insecure=args.insecure) as agent,
            serving(
                args.monitor, agent.robot, args.record, meta, foxglove=args.foxglove
            ) as monitor,
        ):
            if monitor is not None:
                monitor.add_agent(agent)
            joining.watch(agent)
            transport = agent.system.transport
            endpoint = getattr(transport, "endpoint", "?")
            print(listening(agent.robot, endpoint), flush=True)
            if args.until_stdin_closes and watchable(sys.stdin):
                await stdin_closed()
            else:
                await anyio.sleep_forever()

    _until_stopped(serve, args, functools.partial(joining.stopping, "leaving the team"))
    return 0  # standard input closed (--until-stdin-closes)


# -- btcap team status -------------------------------------------------------------------
def _status(args: argparse.Namespace) -> int:
    from btcap.cli.teamwords import Joining, departure_rows
    from btcap.team.deployment.departed import DepartureView, survey_departures
    from btcap.team.deployment.observer import open_observer, survey

    config = _config(args.config)
    seen: list[str] = []
    refused: list[str] = []

    async def look() -> tuple[bool, list[MemberView], list[DepartureView]]:
        async with open_observer(config, member=args.robot) as observer:
            seen.append(observer.id)
            complete, members = await survey(observer, config.seeds, timeout_s=args.wait)
            answered = [m.robot for m in members if m.capabilities is not None]
            departed = await survey_departures(observer, answered)
            if observer.transport is not None:
                refused.extend(observer.transport.stats.refused_by.values())
            return complete, members, departed

    complete, members, departed = _until_stopped(look, args, "stopping")
    _print_team(seen[0] if seen else config.robot, members)
    if departed:
        print(f"departed lately: {len(departed)}")
        _print_rows(departure_rows(departed))
    answered = {m.robot for m in members if m.capabilities is not None}
    joining = Joining(config.seeds)
    for seed in sorted(set(config.seeds) - answered):
        said = joining.silent([seed], "; ".join(refused))
        print(f"btcap: seed {seed} did not answer within {args.wait} s: {said}", file=sys.stderr)
    return 0 if answered and complete else 1


def _print_team(robot: str, members: list[MemberView]) -> None:
    print(f"team seen by {robot} (an observer, not a member): {len(members)} member(s)")
    rows = [("robot", "heartbeat", "capabilities", "runs", "completed")]
    for m in members:
        caps = "(not known yet)" if m.capabilities is None else ", ".join(sorted(m.capabilities))
        runs = "(no answer)" if m.running is None else ", ".join(m.running) or "idle"
        age = f"{m.heartbeat_age_s:.2f} s ago"
        rows.append((m.robot, age, caps or "-", runs, ", ".join(m.succeeded) or "-"))
    _print_rows(rows)


def _print_rows(rows: Sequence[tuple[str, ...]]) -> None:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for r in rows:
        print("  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip())


# -- btcap mission run -------------------------------------------------------------------
def _mission(args: argparse.Namespace) -> int:
    from btcap.bt.files import load_tree
    from btcap.cli.monitor import serving
    from btcap.cli.teamwords import Joining
    from btcap.team.deployment.agentconfig import AgentConfigError
    from btcap.team.deployment.deploy import open_agent, run_mission_file

    config = _config(args.config)
    registry = _registry(args)
    try:
        config.load_capabilities(registry, implementations=False)
    except AgentConfigError as exc:
        raise CliError(str(exc)) from None
    if not args.tree.is_file():
        raise CliError(f"{args.tree}: no such file")
    load_tree(args.tree, registry)  # a bad tree fails before joining (TreeError: exit 1)
    robot = args.robot or config.robot
    joining = Joining(config.seeds)

    async def run() -> MissionReport:
        fox = args.foxglove is not None
        wanted = args.monitor is not None or args.record is not None or fox
        mcap = args.record is not None and args.record.suffix.lower() == ".mcap"
        await _monitor_imports(wanted, serve=args.monitor is not None, foxglove=fox, mcap=mcap)
        async with (
            open_agent(config, registry, robot=robot, missions=True) as agent,
            serving(
                args.monitor,
                f"mission {args.tree.name}",
                args.record,
                {"tree": str(args.tree), "robot": robot},
                foxglove=args.foxglove,
            ) as monitor,
        ):
            if monitor is not None:
                monitor.add_agent(agent)
            joining.watch(agent)
            await _join(agent, config, args.wait, joining)
            shown = None if monitor is None else functools.partial(monitor.add_tree, robot=robot)
            report = await run_mission_file(
                agent, args.tree, registry, timeout_s=args.timeout, progress=_say, on_tree=shown
            )
            if monitor is not None:
                monitor.finish(*_outcome(report, args.tree.name))
            return report

    try:
        doing = functools.partial(joining.stopping, "mission interrupted, leaving the team")
        report = _until_stopped(run, args, doing)
    except TreeError as exc:
        raise CliError(str(exc), code=1) from None
    _print_summary(report)
    return 0 if report.succeeded else 1


def _outcome(report: MissionReport, name: str) -> tuple[str, str]:
    """How the monitor says the mission ended: (result, a line for a person)."""
    after = f"after {report.elapsed_s:.1f} s"
    if report.timed_out:
        return "failed", f"mission {name} timed out {after}"
    result = "succeeded" if report.succeeded else "failed"
    return result, f"mission {name} {result} {after}"


def _say(line: str) -> None:
    try:
        print(line, flush=True)
    except UnicodeEncodeError:  # e.g. "beta failed — re-auctioning" to an ASCII-only pipe
        plain = line.replace("\u2014", "-").encode(sys.stdout.encoding, "backslashreplace")
        print(plain.decode(sys.stdout.encoding), flush=True)


async def _join(agent: Agent, config: RobotConfig, wait: float, joining: Joining) -> None:
    from btcap.team.deployment.deploy import wait_for_team

    complete = await wait_for_team(agent, config.seeds, timeout_s=wait)
    members = ", ".join(sorted(agent.team.members))
    missing = sorted(set(config.seeds) - set(agent.team.members))
    if missing and not members:  # a mission nobody could take: say so now, not at --timeout
        raise CliError(
            f"no seed answered within {wait} s, so the mission was not started: "
            f"{joining.silent(missing)}",
            code=1,
        )
    print(
        f"{agent.robot} joined the team: {members}"
        if members
        else f"{agent.robot} has no teammates: nobody answered",
        flush=True,
    )
    if not complete and missing:
        print(
            f"btcap: seeds {', '.join(missing)} did not answer within {wait} s "
            f"(going on): {joining.silent(missing)}",
            file=sys.stderr,
        )


def _print_summary(report: MissionReport) -> None:
    outcome = "timed out" if report.timed_out else report.state.value
    print(f"mission {outcome} after {report.elapsed_s:.2f} s")
    for cap in report.capabilities:
        robots = " -> ".join(cap.robots) or "nobody"
        outputs = ", ".join(f"{k}={v!r}" for k, v in cap.outputs.items())
        print(f"  {cap.path}: {cap.state.value} on {robots}" + (f" ({outputs})" if outputs else ""))
