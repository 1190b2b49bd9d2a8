"""The ``btcap`` command: ``btcap tree validate|show|dot|nodes`` (more commands plug in).

Adding a command: write a module with ``add_parser(subparsers)`` that adds its parser
and sets ``handler=fn`` (``fn(args) -> int`` exit code) via ``set_defaults``, then list
it in :func:`_command_modules`. Handlers raise :class:`CliError` for usage problems
(exit 2) and may let :class:`~btcap.bt.state.TreeError` escape (printed, exit 1).

This is the only place (with the benchmarks) that configures logging.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

from btcap.actors import configure_logging
from btcap.bt.files import file_info, load_tree, validate_file
from btcap.bt.ports import type_name
from btcap.bt.registry import NodeRegistry, default_registry
from btcap.bt.render import render_dot, render_text
from btcap.bt.state import TreeError

__all__ = ["CliError", "build_parser", "main"]


class CliError(Exception):
    """A usage problem (bad argument, missing file): printed without a traceback."""

    def __init__(self, message: str, code: int = 2) -> None:
        super().__init__(message)
        self.code = code


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
    return ["btcap.cli", "btcap.teamcli", "btcap.keys_cli", "btcap.monitor.cli", *plugins]


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
    """Run the CLI and return the exit code (0 ok, 1 invalid input, 2 usage error)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or an argparse usage error
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    configure_logging(args.log_level, json=args.log_json)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except CliError as exc:
        print(f"btcap: error: {exc}", file=sys.stderr)
        return exc.code
    except TreeError as exc:
        print(exc, file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("btcap: interrupted", file=sys.stderr)
        return 130


# -- btcap tree ... -------------------------------------------------------------------
def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``btcap tree`` and its subcommands."""
    tree = subparsers.add_parser(
        "tree", help="check and inspect tree files", description="Check and inspect tree files."
    )
    tree.set_defaults(handler=_usage(tree))
    cmds = tree.add_subparsers(dest="tree_command", metavar="SUBCOMMAND")

    p = cmds.add_parser("validate", help="check tree files; print 'ok' or every problem")
    p.add_argument("files", nargs="+", metavar="FILE", type=Path)
    p.set_defaults(handler=_validate)

    p = cmds.add_parser("show", help="print a tree as an indented outline")
    p.add_argument("file", metavar="FILE", type=Path)
    p.set_defaults(handler=_show)

    p = cmds.add_parser("dot", help="write a tree as Graphviz DOT")
    p.add_argument("file", metavar="FILE", type=Path)
    p.add_argument("-o", "--output", type=Path, help="write here instead of stdout")
    p.set_defaults(handler=_dot)

    p = cmds.add_parser("nodes", help="list the node types files may use, with their ports")
    p.add_argument("types", nargs="*", metavar="TYPE", help="only these types")
    p.set_defaults(handler=_nodes)


def _registry(args: argparse.Namespace) -> NodeRegistry:
    return default_registry(plugins=not args.no_plugins)


def _existing(path: Path) -> Path:
    if not path.exists():
        raise CliError(f"{path}: no such file")
    if path.is_dir():
        raise CliError(f"{path}: is a directory, expected a tree file")
    return path


def _validate(args: argparse.Namespace) -> int:
    registry = _registry(args)
    code = 0
    for path in args.files:
        if not path.exists() or path.is_dir():
            what = "no such file" if not path.exists() else "is a directory"
            print(f"btcap: error: {path}: {what}", file=sys.stderr)
            code = 2
            continue
        problems = validate_file(path, registry)
        if problems:
            for line in problems:
                print(line, file=sys.stderr)
            code = max(code, 1)
        else:
            print(f"{path}: ok")
    return code


def _show(args: argparse.Namespace) -> int:
    tree = load_tree(_existing(args.file), _registry(args))
    info = file_info(tree)
    if info.description:
        print(info.description)
    sys.stdout.write(render_text(tree))
    return 0


def _dot(args: argparse.Namespace) -> int:
    tree = load_tree(_existing(args.file), _registry(args))
    text = render_dot(tree)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    try:
        args.output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise CliError(f"{args.output}: cannot write: {exc.strerror or exc}") from None
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


def _nodes(args: argparse.Namespace) -> int:
    registry = _registry(args)
    names = args.types or registry.names()
    for name in names:
        try:
            cls = registry.get(name)
        except TreeError as exc:
            raise CliError(str(exc)) from None
        doc = (cls.__doc__ or "").strip().splitlines()
        print(f"{name}: {doc[0] if doc else ''}")
        for kind, ports in (
            ("option", cls.OPTIONS),
            ("input", cls.INPUTS),
            ("output", cls.OUTPUTS),
        ):
            for key, port in ports.items():
                default = "" if port.required else f" = {port.default_value()!r}"
                print(f"  {kind} {key}: {type_name(port.type)}{default}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
