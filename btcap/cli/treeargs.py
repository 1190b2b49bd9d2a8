"""The options of ``btcap tree run`` (apart from :mod:`btcap.cli.tree`, which holds the
other subcommands; argparse only, so ``btcap --help`` stays fast)."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["add_run_arguments"]


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Add the file and the options of ``btcap tree run`` to ``p``."""
    p.add_argument("file", metavar="FILE", type=Path)
    p.add_argument("--rate", type=float, default=10.0, help="ticks per second (default 10)")
    p.add_argument(
        "--timeout",
        default="60",
        metavar="SECONDS",
        help="halt the tree after this many seconds of clock time (virtual with --fast); "
        "0 or none: no limit (default 60)",
    )
    p.add_argument("--max-ticks", type=int, default=None, help="halt after this many ticks")
    p.add_argument(
        "--wake",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="tick again at once when a node asks to (an AsyncSequence that yielded), as "
        "BehaviorTree.CPP's tickWhileRunning; --no-wake: once per period, as its "
        "tickExactlyOnce (default: on for .xml files, off for others)",
    )
    p.add_argument(
        "--fast",
        action="store_true",
        help="virtual time: waits and timeouts pass at once, the run is reproducible",
    )
    p.add_argument(
        "--debug",
        action="store_true",
        help="warn about nodes halted and restarted over and over (also BTCAP_DEBUG=1)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a blackboard entry of a BehaviorTree.CPP XML tree before ticking, as the "
        "application would (repeatable); VALUE is read as the entry's type ('1;2' is a list)",
    )
    p.add_argument(
        "--set-file",
        type=Path,
        default=None,
        metavar="FILE",
        help="a YAML mapping of blackboard entries to set before ticking (--set wins)",
    )
    p.add_argument(
        "--btlog",
        type=Path,
        default=None,
        metavar="OUT.btlog",
        help="log the run as BehaviorTree.CPP's file logger does, for Groot2 to replay "
        "(times from the tree's clock: virtual with --fast)",
    )
