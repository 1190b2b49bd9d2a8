"""``btcap tree run``: tick a tree file to a result, or to a tick or time limit.

Apart from :mod:`btcap.cli.tree` so that ``btcap --help`` never imports what ticking needs.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import msgspec.yaml

from btcap.actors import ManualClock
from btcap.bt.files.btcpp_uses import entry_uses
from btcap.bt.files.btlog import BtlogError, BtlogRecorder
from btcap.bt.leaves import LOG_LOGGER
from btcap.bt.node import Node
from btcap.bt.render import render_text
from btcap.bt.state import DONE, ENDED, State, TreeTimeout
from btcap.bt.tree import Subtree, Tree
from btcap.cli import CliError
from btcap.cli.rostree import bridge_for, wanted
from btcap.team.capabilities.capability import Capability

__all__ = ["run"]


def run(args: argparse.Namespace, load: Callable[[ManualClock | None], Tree]) -> int:
    """``btcap tree run``: tick the tree ``load`` builds, to a result or a limit."""
    if not 0 < args.rate < math.inf:
        raise CliError(f"--rate {args.rate}: expected a finite number of ticks per second > 0")
    if args.max_ticks is not None and args.max_ticks < 1:
        raise CliError(f"--max-ticks {args.max_ticks}: expected at least 1")
    timeout = _timeout(args.timeout)
    if args.fast and wanted(args):
        raise CliError("--fast with --ros: ROS 2 runs on the wall clock, not on virtual time")
    args.entries = _entries(args.set, args.set_file)
    clock = ManualClock() if args.fast else None
    tree = load(clock)
    tree.debug = tree.debug or args.debug
    uses = entry_uses(tree)
    for need in uses.needed(tree.name) if uses else ():
        if need.via or need.key not in args.entries:
            todo = "" if need.via else f" and it was not set (--set {need.key}=VALUE)"
            print(f"{need.where}: line {need.line}: {need.describe()}{todo}", file=sys.stderr)
    caps = [n.path for n in _all_nodes(tree) if isinstance(n, Capability)]
    if caps:
        raise CliError(
            f"{args.file}: capability nodes ({', '.join(caps)}) are run by a team, not by "
            f"'btcap tree run'; run the tree on an agent (btcap mission run)"
        )
    with _log_nodes_shown(), _btlog(tree, args.btlog):
        state, ticks, text, stopped = asyncio.run(_tick(tree, clock, args, timeout))
    sys.stdout.write(text)
    plural = "s" if ticks != 1 else ""
    if stopped is not None:
        if stopped.limit == "max_ticks":
            limit = f"--max-ticks {args.max_ticks}"
        else:
            limit = f"--timeout {timeout:g} s ({'virtual' if args.fast else 'clock'} time)"
        print(
            f"halted after {ticks} tick{plural} at {limit}; still running: "
            f"{', '.join(stopped.running) or 'nothing'}"
        )
        return 3
    print(f"{state.value} after {ticks} tick{plural}")
    if state is State.SUCCEEDED or state is State.SKIPPED:
        return 0
    return 1 if state in DONE else 3


def _entries(given: list[str], file: Path | None) -> dict[str, Any]:
    """``--set-file`` then ``--set``: the blackboard entries the run starts with."""
    out: dict[str, Any] = {}
    if file is not None:
        try:
            data = msgspec.yaml.decode(file.read_bytes())
        except (OSError, msgspec.DecodeError) as exc:
            raise CliError(f"--set-file {file}: {exc}") from None
        if not isinstance(data, dict) or not all(isinstance(k, str) for k in data):
            raise CliError(f"--set-file {file}: expected a mapping of entry names to values")
        out.update(data)
    for item in given:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise CliError(f"--set {item!r}: expected KEY=VALUE")
        out[key.strip()] = value
    return out


def _timeout(text: str) -> float | None:
    """``--timeout``: seconds > 0, or 0/none for no limit."""
    if text.strip().lower() in ("0", "none"):
        return None
    try:
        seconds = float(text)
    except ValueError:
        seconds = math.nan
    if not 0 < seconds < math.inf:
        raise CliError(f"--timeout {text}: expected seconds > 0, or 0 or none for no limit")
    return seconds


@contextlib.contextmanager
def _btlog(tree: Tree, path: Path | None) -> Iterator[None]:
    """``--btlog``: the run logged for Groot2 while it lasts (what was written stays)."""
    if path is None:
        yield
        return
    try:
        recorder = BtlogRecorder(tree, path)
    except OSError as exc:
        raise CliError(f"--btlog {path}: cannot write: {exc.strerror or exc}") from None
    except BtlogError as exc:
        raise CliError(f"--btlog {exc}") from None
    try:
        yield
    finally:
        recorder.close()
        print(f"wrote {path} ({recorder.transitions} transitions)", file=sys.stderr)


@contextlib.contextmanager
def _log_nodes_shown() -> Iterator[None]:
    """Let Log nodes' lines through (info and up) whatever --log-level hides, for the run."""
    logger = logging.getLogger(LOG_LOGGER)
    level = logger.level
    logger.setLevel(min(logging.INFO, logging.getLogger().getEffectiveLevel()))
    try:
        yield
    finally:
        logger.setLevel(level)


def _all_nodes(tree: Tree) -> Iterator[Node]:
    for node in tree.nodes():
        yield node
        if isinstance(node, Subtree):
            yield from _all_nodes(node.inner)


async def _tick(
    tree: Tree, clock: ManualClock | None, args: argparse.Namespace, timeout: float | None
) -> tuple[State, int, str, TreeTimeout | None]:
    """Tick to a result or a limit; the outline is taken before shutdown repaints it."""
    ticks = 0

    def count(state: State) -> bool:
        nonlocal ticks
        ticks += 1
        return state in ENDED

    wake = args.wake if args.wake is not None else args.file.suffix.lower() == ".xml"
    stopped: TreeTimeout | None = None
    jumps = clock.autojump() if clock is not None else contextlib.nullcontext()
    try:
        async with bridge_for(args, tree), jumps:
            try:
                state = await tree.run(
                    args.rate, until=count, max_ticks=args.max_ticks, timeout_s=timeout, wake=wake
                )
            except TreeTimeout as exc:
                state, stopped = exc.state, exc
        return state, ticks, render_text(tree, states=True), stopped
    finally:
        await tree.shutdown()
