"""``btcap sim serve``: the simulated world behind ROS 2 on its own, for robots whose
agents run in processes of their own (:mod:`btcap.sim.ros2.serve`). The parser only:
the handler imports what it needs when it runs, so ``btcap --help`` stays fast."""

from __future__ import annotations

import argparse
import math

__all__ = ["add_parser"]


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sim",
        help="the simulated world on its own (serve its robots to agents elsewhere)",
        description="The simulated world without a mission.",
    )
    what = p.add_subparsers(dest="sim_command", metavar="SUBCOMMAND")
    s = what.add_parser(
        "serve",
        help="serve a scenario's robots behind ROS 2 until stopped",
        description="Serve a scenario's world and robots behind ROS 2 (each robot's "
        "navigate_to_pose, explore/identify/decontaminate actions, pose and state topics "
        "and stop service, in its namespace of the scenario's `ros` block, default "
        "/ROBOT) until SIGINT or SIGTERM, for `btcap agent` processes whose agent files "
        "have a `ros:` block and RosAction implementations (examples/ros2/sim). Runs no "
        "mission: `btcap mission run` gives the agents their work. Needs `make ros-sim` "
        "(.venv-ros/bin/python -m btcap sim serve ...).",
    )
    s.add_argument("scenario", help="a built-in scenario's name or a scenario file")
    s.add_argument(
        "--ros2",
        action="store_true",
        help="behind ROS 2 (the only way it serves, and the default; for clarity)",
    )
    s.add_argument("--speedup", type=float, help="override the scenario's clock speed-up")
    s.set_defaults(handler=_serve)

    def usage(_args: argparse.Namespace) -> int:
        p.print_help()
        return 2

    p.set_defaults(handler=usage)


def _serve(args: argparse.Namespace) -> int:
    import asyncio
    import signal

    from btcap.cli import CliError
    from btcap.sim.mission.scenario import ScenarioError, resolve_scenario
    from btcap.sim.ros2 import ros2_missing
    from btcap.sim.ros2.serve import Served, serve
    from btcap.sim.running.stopper import STOPPED_BY, Stopper

    try:
        s = resolve_scenario(args.scenario)
    except ScenarioError as exc:
        raise CliError(str(exc)) from None
    if args.speedup is not None:
        if not (math.isfinite(args.speedup) and args.speedup > 0):
            raise CliError(f"--speedup: expected a number > 0, got {args.speedup:g}")
        s.speedup = args.speedup
    if (why := ros2_missing()) is not None:
        raise CliError(why if s.ros is None else f"{s.source}: ros: {why}")

    def ready(namespaces: dict[str, str]) -> None:
        where = ", ".join(f"{robot} at {ns}" for robot, ns in namespaces.items())
        print(f"serving {s.name} behind ROS 2: {where} (stop: Ctrl-C)", flush=True)

    async def main(stopper: Stopper) -> Served:
        try:
            return await serve(s, stop=stopper.event(), ready=ready)
        except ScenarioError as exc:
            raise CliError(str(exc)) from None

    with Stopper() as stopper:
        served = asyncio.run(main(stopper))
    for robot, goals in served.items():
        took = ", ".join(f"{action} {n}" for action, n in sorted(goals.items())) or "nothing"
        print(f"served {robot}: {took}", flush=True)
    if stopper.signum is not None:
        return STOPPED_BY[signal.Signals(stopper.signum)]
    return 0
