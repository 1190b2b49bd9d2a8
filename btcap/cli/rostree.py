"""ROS 2 for ``btcap tree``: ``--ros`` and its options, the ROS node types in the
registry, the robot's bridge for ``btcap tree run``, and the line that says a file's
node needs ROS when it is not configured or not installed.

Nothing here imports :mod:`btcap.ros` (nor rclpy) unless ``--ros`` is given.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import re
from collections.abc import AsyncIterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from btcap.cli import CliError

if TYPE_CHECKING:
    from btcap.bt.registry import NodeRegistry
    from btcap.bt.tree import Tree

__all__ = [
    "ROS_TYPES",
    "add_ros_options",
    "bridge_for",
    "ros_problems",
    "use_ros",
    "wanted",
]

#: The node types of btcap.ros (its ``NODE_TYPES``), by name: known without importing it.
ROS_TYPES = ("RosAction", "RosService", "RosPublish", "RosSubscribe", "RosWaitForMessage")

_UNKNOWN = re.compile(r"unknown node type '(" + "|".join(ROS_TYPES) + r")'")
_COUNT = re.compile(r": \d+ unknown node types: ")


def add_ros_options(parser: argparse.ArgumentParser) -> None:
    """The ``ROS 2`` option group of ``btcap tree`` subcommands."""
    group = parser.add_argument_group("ROS 2 (docs/ros2.md)")
    group.add_argument(
        "--ros",
        action="store_true",
        help="the tree uses ROS 2 nodes (RosAction, RosService, ...): register them and, "
        "for 'run', join ROS 2 as the robot's node (implied by the options below)",
    )
    group.add_argument(
        "--ros-namespace",
        metavar="NS",
        help="the robot's namespace, where relative action, service and topic names "
        "resolve (e.g. /husky1; default '/')",
    )
    group.add_argument(
        "--ros-domain", type=int, metavar="ID", help="ROS domain id (default: ROS_DOMAIN_ID or 0)"
    )
    group.add_argument(
        "--ros-settings",
        type=Path,
        metavar="FILE",
        help="a YAML file with the robot's ROS settings: an agent file's 'ros:' block, or "
        "the agent file itself (the options above override it)",
    )


def wanted(args: argparse.Namespace) -> bool:
    return bool(
        getattr(args, "ros", False)
        or getattr(args, "ros_namespace", None) is not None
        or getattr(args, "ros_domain", None) is not None
        or getattr(args, "ros_settings", None) is not None
    )


def use_ros(args: argparse.Namespace, registry: NodeRegistry) -> None:
    """With ``--ros``: rclpy loaded (one line if it cannot be) and the ROS node types in
    ``registry``."""
    if not wanted(args):
        return
    from btcap.ros.agent import register
    from btcap.ros.errors import RosError
    from btcap.ros.loader import load

    try:
        load()
    except RosError as exc:
        raise CliError(f"--ros: {exc}") from None
    register(registry)


def _settings(args: argparse.Namespace) -> Any:
    import msgspec
    import msgspec.yaml

    from btcap.team.rossettings import RosSettings

    given: dict[str, Any] = {}
    path: Path | None = args.ros_settings
    if path is not None:
        try:
            data = msgspec.yaml.decode(path.read_bytes())
        except (OSError, msgspec.DecodeError) as exc:
            raise CliError(f"--ros-settings {path}: cannot read: {exc}") from None
        if isinstance(data, dict) and isinstance(data.get("ros"), dict):
            data = data["ros"]
        if not isinstance(data, dict):
            raise CliError(f"--ros-settings {path}: expected a mapping (a 'ros:' block)")
        given.update(data)
    if args.ros_namespace is not None:
        given["namespace"] = args.ros_namespace
    if args.ros_domain is not None:
        given["domain_id"] = args.ros_domain
    try:
        return msgspec.convert(given, RosSettings)
    except (msgspec.ValidationError, ValueError) as exc:
        where = f"--ros-settings {path}" if path is not None else "--ros options"
        raise CliError(f"{where}: {exc}") from None


@contextlib.asynccontextmanager
async def bridge_for(args: argparse.Namespace, tree: Tree) -> AsyncIterator[None]:
    """With ``--ros``: the robot's bridge, started in a worker thread, given to every
    ROS node of ``tree`` (Subtrees' too) and closed after; else nothing."""
    if not wanted(args):
        yield
        return
    from btcap.ros.base import give
    from btcap.ros.client import RosBridge
    from btcap.ros.errors import RosError

    settings = _settings(args)
    bridge = RosBridge(settings)
    try:
        await bridge.__aenter__()
    except RosError as exc:
        raise CliError(f"--ros: {exc}") from None
    try:
        give(bridge, tree)
        yield
    finally:
        await bridge.__aexit__(None, None, None)


def ros_problems(problems: list[str], args: argparse.Namespace) -> list[str]:
    """``problems`` with each "unknown node type" of a ROS node type said as what it is:
    a node that needs ROS 2, and how to get it."""
    found = [m for p in problems if (m := _UNKNOWN.search(p))]
    if not found:
        return problems
    if importlib.util.find_spec("rclpy") is None:
        how = (
            "ROS 2 is not installed in this Python: install it with `make ros`, then run "
            "`.venv-ros/bin/python -m btcap tree ... --ros` (docs/ros2.md)"
        )
    else:
        how = "add --ros (and --ros-namespace NS: the robot's namespace)"
    out: list[str] = []
    for p in problems:
        m = _UNKNOWN.search(p)
        if m is None:
            if not (_COUNT.search(p) and len(found) > 1):
                out.append(p)
            continue
        out.append(f"{p[: m.start()]}node type {m[1]!r} needs ROS 2: {how}")
    return out
