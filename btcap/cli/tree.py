"""``btcap tree validate|show|dot|run|nodes``: check, print, draw and tick tree files.

Every subcommand takes ``--load MODULE`` (your own node types) and ``--interfaces FILE``
(capability interfaces, whose nodes and bridges trees use), so a tree is checked with
the node types it will really run with. Files are YAML, JSON or BehaviorTree.CPP v4 XML.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import re
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

from btcap.bt.state import TreeError
from btcap.cli import CliError
from btcap.cli.rostree import add_ros_options, ros_problems, use_ros
from btcap.cli.treeargs import add_run_arguments

if TYPE_CHECKING:  # the rest is imported by the subcommand that runs: --help stays fast
    from btcap.actors import ManualClock
    from btcap.bt.registry import NodeRegistry
    from btcap.bt.tree import Tree

__all__ = ["add_parser"]


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``btcap tree`` and its subcommands."""
    tree = subparsers.add_parser(
        "tree",
        help="check, inspect and run tree files",
        description="Check, inspect and run tree files (YAML, JSON or BehaviorTree.CPP v4 XML).",
    )
    tree.set_defaults(handler=_help(tree))
    cmds = tree.add_subparsers(dest="tree_command", metavar="SUBCOMMAND")
    types = argparse.ArgumentParser(add_help=False)
    group = types.add_argument_group("node types")
    group.add_argument(
        "--load",
        action="append",
        default=[],
        metavar="MODULE",
        help="import a module (dotted name or .py file) and register its Node classes and "
        "CapabilityInterfaces; MODULE:NAME registers what NAME is or returns (repeatable)",
    )
    group.add_argument(
        "--interfaces",
        action="append",
        default=[],
        metavar="FILE",
        type=Path,
        help="capability interface file: its capabilities and their <Name>Inputs/"
        "<Name>Outputs bridges become node types (repeatable)",
    )
    add_ros_options(types)

    xml = argparse.ArgumentParser(add_help=False)
    group = xml.add_argument_group("BehaviorTree.CPP XML")
    group.add_argument(
        "--main",
        metavar="TREE",
        help="the <BehaviorTree ID> to run (default: main_tree_to_execute, or the only one)",
    )
    group.add_argument(
        "--stub-missing",
        action="store_true",
        help="build each type <TreeNodesModel> declares but nothing registers, with its "
        "ports; actions and conditions succeed (or do what --stub-script says)",
    )
    group.add_argument(
        "--model",
        action="append",
        default=[],
        metavar="FILE",
        type=Path,
        help="a model file (<root><TreeNodesModel>, e.g. nav2_tree_nodes.xml) read besides "
        "the tree's own models (repeatable)",
    )
    group.add_argument(
        "--stub-script",
        metavar="FILE",
        type=Path,
        help="YAML file of the stubs' results by type or name, e.g. "
        "'types: {ComputePathToPose: [RUNNING, SUCCESS]}'",
    )
    files = argparse.ArgumentParser(add_help=False, parents=[types, xml])

    p = cmds.add_parser(
        "validate", parents=[files], help="check tree files; print 'ok' or every problem"
    )
    p.add_argument("files", nargs="+", metavar="FILE", type=Path)
    p.set_defaults(handler=_validate)

    p = cmds.add_parser("show", parents=[files], help="print a tree as an indented outline")
    p.add_argument("file", metavar="FILE", type=Path)
    p.set_defaults(handler=_show)

    p = cmds.add_parser(
        "dot",
        parents=[files],
        help="draw a tree: Graphviz DOT, or SVG/PNG/PDF by the output's suffix",
    )
    p.add_argument("file", metavar="FILE", type=Path)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        help="write here instead of stdout; .svg, .png or .pdf are rendered with Graphviz",
    )
    p.set_defaults(handler=_dot)

    p = cmds.add_parser(
        "run",
        parents=[files],
        help="tick a tree until it succeeds or fails; print its final states",
        description="Tick a tree at --rate until it succeeds or fails (exit 0 or 1), then "
        "print it with states. At --timeout (default 60 s) or --max-ticks it is halted and "
        "a last line names the nodes still running (exit 3). Log nodes print to stderr.",
    )
    add_run_arguments(p)
    p.set_defaults(handler=_run)

    p = cmds.add_parser(
        "nodes", parents=[types], help="list the node types files may use, with their ports"
    )
    p.add_argument("types", nargs="*", metavar="TYPE", help="only these types")
    p.set_defaults(handler=_nodes)


def _help(parser: argparse.ArgumentParser) -> Callable[[argparse.Namespace], int]:
    def show(args: argparse.Namespace) -> int:
        parser.print_help(sys.stderr)
        return 2

    return show


# -- node types -------------------------------------------------------------------------
def _registry(args: argparse.Namespace) -> NodeRegistry:
    from btcap.bt.registry import default_registry
    from btcap.team.capabilities.capfiles import load_interfaces, register_interfaces

    registry = default_registry(plugins=not args.no_plugins)
    for ref in args.load:
        _register(registry, ref)
    for path in args.interfaces:
        if not path.is_file():
            raise CliError(f"--interfaces {path}: no such file")
        register_interfaces(registry, load_interfaces(path, registry))
    use_ros(args, registry)
    return registry


def _import(name: str) -> ModuleType:
    """A module by dotted name (the current directory first on the path) or by file."""
    try:
        if name.endswith(".py"):
            path = Path(name)
            if not path.is_file():
                raise CliError(f"--load {name}: no such file")
            if path.stem in sys.modules:
                raise CliError(f"--load {name}: a module named {path.stem!r} is already loaded")
            spec = importlib.util.spec_from_file_location(path.stem, path)
            if spec is None or spec.loader is None:
                raise CliError(f"--load {name}: not an importable Python file")
            module = importlib.util.module_from_spec(spec)
            sys.modules[path.stem] = module
            spec.loader.exec_module(module)
            return module
        if "" not in sys.path:
            sys.path.insert(0, "")  # as `python -m` does: your modules in this directory
        return importlib.import_module(name)
    except CliError:
        raise
    except Exception as exc:  # the user's module: any error is theirs to see
        raise CliError(f"--load {name}: import failed: {type(exc).__name__}: {exc}") from exc


def _register(registry: NodeRegistry, ref: str) -> None:
    """Register what ``MODULE`` defines or what ``MODULE:NAME`` is or returns."""
    from btcap.bt.node import Node
    from btcap.team.capabilities.capability import CapabilityInterface
    from btcap.team.capabilities.capfiles import register_interfaces

    module_name, _, attr = ref.partition(":")
    module = _import(module_name)
    items: list[object]
    if attr:
        if not hasattr(module, attr):
            raise CliError(f"--load {ref}: module {module_name!r} has no {attr!r}")
        found = getattr(module, attr)
        if isinstance(found, type | CapabilityInterface):
            items = [found]
        elif callable(found):
            try:
                items = list(found())
            except Exception as exc:  # the user's function: any error is theirs to see
                raise CliError(f"--load {ref}: {type(exc).__name__}: {exc}") from exc
        else:
            raise CliError(f"--load {ref}: expected a Node class, an interface or a function")
    else:
        items = [
            v
            for k, v in vars(module).items()
            if not k.startswith("_")
            and (
                isinstance(v, CapabilityInterface)
                or getattr(v, "__module__", "") == module.__name__
            )
        ]
    register_interfaces(registry, [i for i in items if isinstance(i, CapabilityInterface)])
    for cls in items:
        if isinstance(cls, type) and issubclass(cls, Node):
            if cls in registry.classes():
                continue  # imported twice, or re-exported
            try:  # a btcap built-in's name is taken as user.NAME (NodeRegistry.register)
                registry.register(cls)
            except TreeError as exc:
                raise CliError(f"--load {ref}: {exc}; rename the class") from None
        elif attr and not isinstance(cls, CapabilityInterface):
            raise CliError(f"--load {ref}: {cls!r} is neither a Node class nor an interface")


_UNKNOWN = re.compile(r"unknown node type '([^']+)'")


def _hints(path: Path, problems: list[str], args: argparse.Namespace) -> list[str]:
    """Point at the interface file next to a tree that would define its unknown types.

    Only a hint: which interfaces a tree runs with is the user's choice, so nothing is
    loaded that was not asked for.
    """
    from btcap.team.capabilities.capfiles import load_interfaces

    unknown = dict.fromkeys(m[1] for p in problems for m in _UNKNOWN.finditer(p))
    if not unknown or args.interfaces:
        return []
    out: list[str] = []
    for candidate in sorted(path.parent.glob("*")):
        if candidate.suffix not in (".yaml", ".yml", ".json") or not candidate.is_file():
            continue
        try:
            if b"btcap_interfaces" not in candidate.read_bytes()[:4096]:
                continue
            names = {i.name for i in load_interfaces(candidate)}
        except (OSError, TreeError):
            continue
        for kind in unknown:
            base = kind.removesuffix("Inputs").removesuffix("Outputs")
            if base in names:
                out.append(
                    f"hint: {kind!r} comes from capability interface {base!r} in "
                    f"{candidate}; add --interfaces {candidate}"
                )
    return out


def _xml_options(args: argparse.Namespace) -> dict[str, Any]:
    """The load_tree keywords of the BehaviorTree.CPP XML options."""
    for path in [*args.model, *([args.stub_script] if args.stub_script else [])]:
        if not path.is_file():
            raise CliError(f"{path}: no such file")
    return {
        "main": args.main,
        "stub_missing": args.stub_missing,
        "models": args.model,
        "stub_script": args.stub_script,
    }


@contextlib.contextmanager
def _warnings_shown() -> Iterator[None]:
    """Print what files only warn about (BehaviorTree.CPP's warnings) as one line each."""
    from btcap.bt.files import TreeFileWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", TreeFileWarning)
        try:
            yield
        finally:
            for w in caught:
                if issubclass(w.category, TreeFileWarning):
                    print(f"warning: {w.message}", file=sys.stderr)
                else:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _load(args: argparse.Namespace, path: Path, clock: ManualClock | None = None) -> Tree:
    from btcap.bt.files import TreeFileError, load_tree

    registry = _registry(args)
    try:
        with _warnings_shown():
            return load_tree(
                _existing(path),
                registry,
                clock=clock,
                entries=getattr(args, "entries", None),
                **_xml_options(args),
            )
    except TreeFileError as exc:
        problems = [*exc.problems, *_hints(path, exc.problems, args)]
        raise TreeFileError(ros_problems(problems, args)) from None


# -- subcommands ------------------------------------------------------------------------
def _existing(path: Path) -> Path:
    if not path.exists():
        raise CliError(f"{path}: no such file")
    if path.is_dir():
        raise CliError(f"{path}: is a directory, expected a tree file")
    return path


def _validate(args: argparse.Namespace) -> int:
    from btcap.bt.files import validate_file

    registry = _registry(args)
    options = _xml_options(args)
    code = 0
    for path in args.files:
        if not path.exists() or path.is_dir():
            what = "no such file" if not path.exists() else "is a directory"
            print(f"btcap: error: {path}: {what}", file=sys.stderr)
            code = 2
            continue
        with _warnings_shown():
            problems = validate_file(path, registry, **options)
        problems = ros_problems(problems + _hints(path, problems, args), args)
        if problems:
            for line in problems:
                print(line, file=sys.stderr)
            code = max(code, 1)
        else:
            print(f"{path}: ok")
    return code


def _show(args: argparse.Namespace) -> int:
    from btcap.cli.treeshow import show

    return show(_load(args, args.file))


def _dot(args: argparse.Namespace) -> int:
    from btcap.cli.treeshow import dot

    return dot(_load(args, args.file), args.output)


def _run(args: argparse.Namespace) -> int:
    from btcap.cli.treerun import run

    return run(args, lambda clock: _load(args, args.file, clock))


def _nodes(args: argparse.Namespace) -> int:
    from btcap.bt.ports import bounds, type_name

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
                rule = f" {bounds(port.meta)}" if port.meta is not None else ""
                print(f"  {kind} {key}: {type_name(port.type)}{rule}{default}")
    return 0
