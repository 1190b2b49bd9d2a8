"""The ``btcap`` command: each subcommand lives in its own module (``btcap tree`` in
:mod:`btcap.cli.tree`), listed by :func:`_command_modules` or plugged in.

Adding a command: write a module with ``add_parser(subparsers)`` that adds its parser
and sets ``handler=fn`` (``fn(args) -> int`` exit code) via ``set_defaults``, then list
it in :func:`_command_modules`. Handlers raise :class:`CliError` for usage problems
(exit 2), may let :class:`~btcap.bt.state.TreeError` escape (printed, exit 1), and raise
:class:`Stopped` once a signal has stopped them cleanly. Keep ``add_parser`` cheap: a
handler imports what it needs when it runs, so ``btcap --help`` stays fast.

This is the only place (with the benchmarks) that configures logging.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Protocol

from btcap.bt.state import NodeErrorWarning, TreeError, UnassignableWarning
from btcap.errors import BtcapError, HandshakeWarning

__all__ = [
    "CliError",
    "Stopped",
    "build_parser",
    "configure_logging",
    "main",
]


class CliError(BtcapError):
    """A usage problem (bad argument, missing file): printed without a traceback."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code


class Stopped(BtcapError):
    """A command ended early, cleanly, by SIGINT or SIGTERM, and has said so: the exit
    code is 128 + the signal's number, as a shell reports a process the signal ended."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.code = 128 + signum


class _CommandModule(Protocol):
    def add_parser(
        self, subparsers: argparse._SubParsersAction[argparse.ArgumentParser]
    ) -> None: ...


def _command_modules() -> list[str]:
    """Modules that contribute top-level subcommands, in help order.

    Register a new command by appending its module here, or, from a package above
    btcap (``btcap run`` lives in ``sim``), by an entry point in the group
    ``btcap.commands`` naming the module, so btcap never imports the layers above it.
    """
    from importlib.metadata import entry_points

    plugins = sorted(ep.value for ep in entry_points(group="btcap.commands"))
    return ["btcap.cli.tree", "btcap.cli.team", "btcap.cli.keys", "btcap.cli.monitor", *plugins]


def configure_logging(level: str, *, json: bool = False) -> None:
    """:func:`btcap.actors.configure_logging`, imported once a command runs: printing
    help needs neither the actor runtime nor structlog."""
    from btcap.actors import configure_logging as configure

    configure(level, json=json)


def _version() -> str:
    from btcap import __version__

    return __version__


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (exposed for docs and tests)."""
    parser = argparse.ArgumentParser(
        prog="btcap",
        description="Behavior trees with capabilities: check, inspect and run trees.",
    )
    parser.add_argument("--version", action="version", version=f"btcap {_version()}")
    parser.add_argument(
        "--log-level",
        default="warning",
        choices=["debug", "info", "warning", "error"],
        help="structured log level (default: warning)",
    )
    parser.add_argument("--log-json", action="store_true", help="log JSON lines to stderr")
    parser.add_argument(
        "--no-plugins",
        action="store_true",
        help="do not load node packages from the 'btcap.nodes' entry points",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _command_modules():
        try:
            module: _CommandModule = importlib.import_module(name)
            module.add_parser(sub)
        except (ImportError, AttributeError) as exc:  # a broken plugin must not break btcap
            print(f"btcap: command plugin {name!r} could not be loaded: {exc}", file=sys.stderr)
    parser.set_defaults(handler=_usage(parser))
    return parser


def _usage(parser: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
    """A handler for a command given without its subcommand: show help, exit 2."""

    def show(args: argparse.Namespace) -> int:
        parser.print_help(sys.stderr)
        return 2

    return show


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return the exit code (0 ok, 1 invalid input, 2 usage error, 128 +
    the signal's number when SIGINT or SIGTERM stopped it)."""
    try:
        parser = build_parser()
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, --version, or an argparse usage error
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
        configure_logging(args.log_level, json=args.log_json)
        # The command's log shows each node error and each capability nobody can take;
        # the warnings that tell a library's user of them by default would say it twice.
        for told in (NodeErrorWarning, UnassignableWarning, HandshakeWarning):
            warnings.filterwarnings("ignore", category=told)
        handler: Callable[[argparse.Namespace], int] = args.handler
        return handler(args)
    except CliError as exc:
        print(f"btcap: error: {exc}", file=sys.stderr)
        return exc.code
    except TreeError as exc:
        print(exc, file=sys.stderr)
        return 1
    except Stopped as exc:  # the command said what it stopped
        return exc.code
    except KeyboardInterrupt:  # Ctrl-C anywhere else: one line, not a traceback
        print("btcap: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
