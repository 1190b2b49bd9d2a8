"""The layering contract of DESIGN.md, checked over every import statement in the code.

``btcap._lazy`` and ``btcap.errors`` (the base of all) <- ``transports`` <- ``actors`` <-
``btcap.bt`` <- ``btcap.team`` <- ``btcap`` (its public API and CLI) <- ``sim`` <-
``bench``: a module may import its own layer and those below, never above; no two modules
import each other, directly or round a longer circle, and that counts imports inside
functions and under ``TYPE_CHECKING`` (a circle hidden there is still a circle a reader
has to untangle). The sans-IO allocation core imports no I/O, and neither do the modules
it imports, nor theirs: checked over the imports that run when a module is imported, and
in a fresh interpreter.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from btcap_sources import ROOTS, modules
from test_startup import _loaded

#: Lowest first. A module belongs to the longest prefix listed here. btcap._lazy (the
#: lazy re-exports of the package ``__init__`` modules) and btcap._enum (an Enum metaclass
#: for hot paths), stdlib only, are the base of all.
LAYERS = (
    "btcap._lazy",
    "btcap._enum",
    "btcap.errors",
    "btcap.transports",
    "btcap.actors",
    "btcap.bt",
    "btcap.team",
    "btcap.ros",
    "btcap",
    "btcap.sim",
    "btcap.bench",
)
#: Top-level names of the folders installed under btcap (pyproject.toml's package-dir).
BARE = tuple(folder.name for package, folder in ROOTS.items() if package != "btcap")
#: What the sans-IO core may not import: it decides, the shell does the I/O.
IO_MODULES = ("asyncio", "anyio", "zmq", "socket", "selectors", "btcap.actors", "time")
CORE = "btcap.team.core"


MODULES = modules()


def _resolve(name: str, path: Path, node: ast.Import | ast.ImportFrom) -> set[str]:
    """The modules one import statement of module ``name`` (file ``path``) names."""
    if isinstance(node, ast.Import):
        return {alias.name for alias in node.names}
    if node.level:
        base = name.split(".")
        base = base[: len(base) - node.level + (1 if path.name == "__init__.py" else 0)]
        mod = ".".join([*base, node.module] if node.module else base)
    else:
        mod = node.module or ""
    out = {mod}
    for alias in node.names:  # ``from btcap.bt import composites`` names a module
        if f"{mod}.{alias.name}" in MODULES:
            out.add(f"{mod}.{alias.name}")
    return out


def _imports(name: str, path: Path) -> set[str]:
    """Every module ``name`` imports, resolved to modules of btcap where it can be."""
    tree = ast.parse(path.read_text(), str(path))
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            out |= _resolve(name, path, node)
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _is_type_checking(test: ast.expr) -> bool:
    """``TYPE_CHECKING`` or ``typing.TYPE_CHECKING``."""
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _run_at_import(body: list[ast.stmt]) -> Iterator[ast.stmt]:
    """The statements of ``body`` that run when the module is imported: not those in
    functions nor under ``if TYPE_CHECKING:`` (its ``else``, and ``if not
    TYPE_CHECKING:``, do run); class bodies, ``try`` and ``with`` do."""
    for stmt in body:
        yield stmt
        if isinstance(stmt, ast.If):
            if not _is_type_checking(stmt.test):
                yield from _run_at_import(stmt.body)
            yield from _run_at_import(stmt.orelse)
        elif isinstance(stmt, ast.Try | ast.TryStar):
            for part in (stmt.body, *(h.body for h in stmt.handlers), stmt.orelse):
                yield from _run_at_import(part)
            yield from _run_at_import(stmt.finalbody)
        elif isinstance(stmt, ast.With | ast.ClassDef | ast.For | ast.While):
            yield from _run_at_import(stmt.body)


def _runtime_imports(name: str, path: Path) -> set[str]:
    """The modules importing ``name`` imports, and the ``__init__`` of each package above
    each of them (``import a.b.c`` runs ``a`` and ``a.b`` first)."""
    tree = ast.parse(path.read_text(), str(path))
    named: set[str] = {name}
    for stmt in _run_at_import(tree.body):
        if isinstance(stmt, ast.Import | ast.ImportFrom):
            named |= _resolve(name, path, stmt)
    out = {".".join(mod.split(".")[:i]) for mod in named for i in range(1, mod.count(".") + 2)}
    return out - {name}


RUNTIME_GRAPH = {name: _runtime_imports(name, path) for name, path in MODULES.items()}


def _layer(module: str) -> int:
    best = -1
    for i, prefix in enumerate(LAYERS):
        if (module == prefix or module.startswith(prefix + ".")) and (
            best < 0 or len(prefix) > len(LAYERS[best])
        ):
            best = i
    return best


def _package(module: str) -> str:
    return LAYERS[_layer(module)]


def test_the_graph_sees_the_whole_package() -> None:
    assert {"btcap.transports.codec", "btcap.actors.system", "btcap.bt.node"} <= MODULES.keys()
    assert {
        "btcap.team.runtime.agent",
        "btcap.sim.running.runner",
        "btcap.bench.speed.tick",
    } <= MODULES.keys()
    assert set(BARE) == {"actors", "transports", "sim", "bench"}


def test_no_module_imports_a_higher_layer() -> None:
    bad = [
        f"{mod} ({LAYERS[_layer(mod)]}) imports {dep} ({LAYERS[_layer(dep)]})"
        for mod, deps in GRAPH.items()
        for dep in deps
        if dep.startswith("btcap") and _layer(dep) > _layer(mod)
    ]
    assert not bad, "\n".join(sorted(bad))


def test_no_bare_top_level_imports() -> None:
    """The folders are installed as btcap.actors etc.: ``import actors`` would load a
    second copy (or another distribution's package of that name)."""
    bad = [
        f"{mod} imports {dep}"
        for mod, deps in GRAPH.items()
        for dep in deps
        if dep.split(".")[0] in BARE
    ]
    assert not bad, "\n".join(sorted(bad))


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles_between_modules() -> None:
    # A package's __init__ re-exports its modules; that is not a circle of logic.
    graph = {
        mod: {d for d in deps if d in MODULES and d != mod and not _is_reexport(mod, d)}
        for mod, deps in GRAPH.items()
        if MODULES[mod].name != "__init__.py"
    }
    cycles = _cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def _is_reexport(mod: str, dep: str) -> bool:
    return MODULES[dep].name == "__init__.py" and mod.startswith(dep + ".")


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.startswith(CORE)))
def test_the_allocation_core_does_no_io(module: str) -> None:
    bad = sorted(
        dep
        for dep in GRAPH[module]
        if any(dep == io or dep.startswith(io + ".") for io in IO_MODULES)
    )
    assert not bad, f"{module} imports {bad}"


#: Imports nothing that does I/O, not even transitively (DESIGN.md: the sans-IO core and
#: the message types), by module prefix -> the third-party packages it may reach.
IO_FREE = {
    "btcap.transports.message": {"msgspec"},
    "btcap.team.messages": {"msgspec"},
    CORE: {"msgspec", "numpy", "scipy"},
}
#: Not reachable from IO_FREE (``time`` is: every interpreter loads it at start-up).
IO_TRANSITIVE = ("asyncio", "anyio", "zmq", "socket", "selectors", "btcap.actors")


def _io_free(module: str) -> set[str] | None:
    """The third-party packages ``module`` may reach, or None if it is not I/O-free."""
    for prefix, allowed in IO_FREE.items():
        if module == prefix or module.startswith(prefix + "."):
            return allowed
    return None


def _first_forbidden(graph: dict[str, set[str]], start: str, allowed: set[str]) -> list[str] | None:
    """The import chain from ``start`` to the first module it may not reach (I/O, the
    actor runtime, a third-party package not ``allowed``), or None (breadth first)."""
    came: dict[str, str | None] = {start: None}
    todo = [start]
    while todo:
        mod = todo.pop(0)
        root = mod.split(".")[0]
        if mod != start and (
            any(mod == io or mod.startswith(io + ".") for io in IO_TRANSITIVE)
            or (root not in sys.stdlib_module_names and root != "btcap" and root not in allowed)
        ):
            chain = [mod]
            while (prev := came[chain[-1]]) is not None:
                chain.append(prev)
            return chain[::-1]
        for dep in sorted(graph.get(mod, ())):
            if dep not in came:
                came[dep] = mod
                todo.append(dep)
    return None


IO_FREE_MODULES = sorted(m for m in MODULES if _io_free(m) is not None)


@pytest.mark.parametrize("module", IO_FREE_MODULES)
def test_the_io_free_modules_import_no_io_even_transitively(module: str) -> None:
    allowed = _io_free(module)
    assert allowed is not None
    chain = _first_forbidden(RUNTIME_GRAPH, module, allowed)
    assert chain is None, "importing it imports " + " -> ".join(chain)


@pytest.mark.parametrize("module", IO_FREE_MODULES)
def test_the_io_free_modules_load_no_io_in_a_fresh_interpreter(module: str) -> None:
    """What really ends up in ``sys.modules`` (third-party packages' own imports too)."""
    loaded = _loaded(f"import {module}")
    assert module in loaded  # the check can see an import
    bad = [io for io in IO_TRANSITIVE if any(m == io or m.startswith(io + ".") for m in loaded)]
    assert not bad, f"importing {module} loads {bad}"


def test_the_checker_catches_what_it_is_for() -> None:
    """The rules above must be able to fail: a circle, an upward import and an I/O
    import a few modules away are seen."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert (
        _layer("btcap.actors.system") < _layer("btcap.bt.node") < _layer("btcap.team.runtime.agent")
    )
    assert _layer("btcap.team.runtime.agent") < _layer("btcap") < _layer("btcap.sim.running.runner")
    assert _layer("btcap._lazy") < _layer("btcap.transports.base")
    planted = {"btcap.x": {"btcap.y", "msgspec"}, "btcap.y": {"btcap.z"}, "btcap.z": {"zmq"}}
    assert _first_forbidden(planted, "btcap.x", {"msgspec"}) == [
        "btcap.x",
        "btcap.y",
        "btcap.z",
        "zmq",
    ]
    assert _first_forbidden(planted, "btcap.x", {"msgspec", "zmq"}) is not None  # I/O: never
    assert _first_forbidden({"btcap.x": {"yaml"}}, "btcap.x", {"msgspec"}) == ["btcap.x", "yaml"]
    assert _first_forbidden({"btcap.x": {"json", "btcap.y"}}, "btcap.x", set()) is None
    code = "import typing\nif typing.TYPE_CHECKING:\n    import zmq\nelse:\n    import json\n"
    code += "if not TYPE_CHECKING:\n    import yaml\ndef f():\n    import anyio\n"
    code += "class C:\n    import csv\n"
    body = _run_at_import(ast.parse(code).body)
    ran = {a.name for s in body if isinstance(s, ast.Import) for a in s.names}
    assert ran == {"typing", "json", "yaml", "csv"}
    assert {"btcap", "btcap.team", "btcap.team.core"} <= RUNTIME_GRAPH["btcap.team.core.body"]


#: Modules are kept small enough to read in one sitting.
MAX_LINES = 450


def test_no_module_is_too_long_to_read() -> None:
    long = {
        mod: n
        for mod, path in MODULES.items()
        if (n := len(path.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"modules over {MAX_LINES} lines: {long}"


#: The team layer's roles, lowest first (DESIGN.md; btcap/team/*/__init__.py say each in
#: a sentence). A team module may import its own level and those below.
TEAM_LEVELS = {
    "btcap.team.consensus_messages": 0,
    "btcap.team.filecheck": 0,
    "btcap.team.ids": 0,
    "btcap.team.messages": 0,
    "btcap.team.observing": 0,
    "btcap.team.settings": 0,
    "btcap.team.rossettings": 0,
    "btcap.team.core": 1,
    "btcap.team.capabilities": 2,
    "btcap.team.demo": 2,
    "btcap.team.membership": 3,
    "btcap.team.allocation": 4,
    "btcap.team.runtime": 5,
    "btcap.team.deployment": 6,
}
#: The simulator's roles (issue 35; sim/*/__init__.py say each in a sentence): the world,
#: the mission on it, running it (in this process, in one process a robot, or behind
#: ROS 1 or ROS 2: hosts of one level), the fault simulation that runs whole teams, and
#: the command line that offers all of them.
SIM_LEVELS = {
    "btcap.sim": 0,  # the package's lazy re-exports of the world's types
    "btcap.sim.world": 0,
    "btcap.sim.mission": 1,
    "btcap.sim.running": 2,
    "btcap.sim.rosbase": 2,
    "btcap.sim.ros1": 2,
    "btcap.sim.ros2": 2,
    "btcap.sim.faults": 3,
    "btcap.sim.cli": 4,
}
#: The benchmarks' roles: shared measuring tools, the benchmarks and probes by kind (none
#: imports another kind), and the command line that runs them.
BENCH_LEVELS = {
    "btcap.bench": 0,
    "btcap.bench.common": 0,
    "btcap.bench.cpumeter": 0,
    "btcap.bench.speed": 1,
    "btcap.bench.allocation": 2,
    "btcap.bench.ros": 2,
    "btcap.bench.attacks": 2,
    "btcap.bench.__main__": 3,
}
ROLES = {"btcap.team": TEAM_LEVELS, "btcap.sim": SIM_LEVELS, "btcap.bench": BENCH_LEVELS}


def _level(levels: dict[str, int], module: str) -> int:
    found = [p for p in levels if module == p or module.startswith(p + ".")]
    assert found, f"{module}: in no role of its layer's levels"
    return levels[max(found, key=len)]


def _modules_of(layer: str) -> list[str]:
    return [m for m in MODULES if m == layer or m.startswith(layer + ".")]


TEAM_MODULES = [m for m in MODULES if m.startswith("btcap.team.")]


@pytest.mark.parametrize("layer", ROLES)
def test_every_module_has_a_role(layer: str) -> None:
    levels = ROLES[layer]
    mods = [m for m in _modules_of(layer) if m != layer or layer in levels]
    assert {_level(levels, m) for m in mods} == set(levels.values())


@pytest.mark.parametrize("layer", ROLES)
def test_no_module_imports_a_higher_role(layer: str) -> None:
    levels = ROLES[layer]
    mods = [m for m in _modules_of(layer) if m != layer or layer in levels]
    upward = sorted(
        f"{m} -> {dep}"
        for m in mods
        for dep in GRAPH[m]
        if dep in MODULES
        and dep.startswith(layer + ".")
        and _level(levels, dep) > _level(levels, m)
    )
    assert not upward, f"modules importing a higher role: {upward}"


def test_roles_of_the_same_level_stay_apart() -> None:
    """Benchmarks of one kind import no other kind's (the attack probes share nothing with
    the allocation runs), so each folder reads on its own."""
    kinds = ("btcap.bench.allocation", "btcap.bench.ros", "btcap.bench.attacks")
    mixed = sorted(
        f"{m} -> {dep}"
        for kind in kinds
        for m in _modules_of(kind)
        for dep in GRAPH[m]
        if any(dep.startswith(other + ".") for other in kinds if other != kind)
    )
    assert not mixed, mixed


def test_team_modules_stay_under_400_lines() -> None:
    long = {m: n for m in TEAM_MODULES if (n := len(MODULES[m].read_text().splitlines())) > 400}
    assert not long, f"team modules over 400 lines: {long}"


def test_nothing_outside_btcap_ros_imports_it() -> None:
    """The bridge is optional (issue 30): only modules that are about ROS themselves (a
    part of their name starts with ``ros``: btcap.bench.ros.ros2, btcap.sim.ros2...) import
    btcap.ros, and nothing imports those; an agent reaches the bridge only through the
    ``btcap.ros`` entry point, when its file has a ``ros:`` block."""

    def about_ros(mod: str) -> bool:
        return any(part.startswith("ros") for part in mod.split(".")[1:])

    # The simulator behind ROS 2 is entered from `btcap run --ros2` only: the CLI's check
    # (btcap.sim.ros2 imports nothing of ROS) and the runner's host, each imported inside
    # the function that runs with --ros2 (the host loads rclpy in a thread).
    # `btcap tree ... --ros` likewise: btcap.cli.rostree imports btcap.ros only inside the
    # functions that run with --ros (its module top imports nothing of it).
    entries = {
        ("btcap.sim.cli", "btcap.sim.ros2"),
        ("btcap.sim.running.runner", "btcap.sim.ros2.host"),
        # and behind ROS 1 from `btcap run --ros1` (or a `backend: ros1` block) alike.
        ("btcap.sim.cli", "btcap.sim.ros1"),
        ("btcap.sim.running.runner", "btcap.sim.ros1.host"),
        ("btcap.cli.tree", "btcap.cli.rostree"),
        ("btcap.cli.treerun", "btcap.cli.rostree"),
    }
    bad = sorted(
        f"{mod} imports {dep}"
        for mod, deps in GRAPH.items()
        if not about_ros(mod)
        for dep in deps
        if dep.startswith("btcap.")
        and about_ros(dep)
        and dep != "btcap.team.rossettings"
        and (mod, dep) not in entries
    )
    assert not bad, "\n".join(bad)


#: Private names a module still takes from another, left to their own change (each entry
#: goes when its name is made public or shared).
PRIVATE_IMPORTS_LEFT: set[tuple[str, str]] = set()


def _private_imports(name: str, path: Path) -> Iterator[tuple[str, str]]:
    """``(module, name)`` for each ``_name`` that module ``name`` imports from another of
    btcap's modules (a private module, ``from btcap import _lazy``, is a module: allowed)."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if not isinstance(node, ast.ImportFrom):
            continue
        source = min(_resolve(name, path, node), key=len)
        for alias in node.names:
            private = alias.name.startswith("_") and not alias.name.startswith("__")
            if private and source in MODULES and f"{source}.{alias.name}" not in MODULES:
                yield source, alias.name


def test_no_module_imports_a_private_name_of_another() -> None:
    """A name starting with ``_`` is its module's own, free to change: another module that
    needs it needs it public (or in a module both share)."""
    bad = sorted(
        f"{mod} imports {private} from {source}"
        for mod, path in MODULES.items()
        for source, private in _private_imports(mod, path)
        if (mod, private) not in PRIVATE_IMPORTS_LEFT
    )
    assert not bad, "\n".join(bad)


def test_the_private_import_check_sees_them(tmp_path: Path) -> None:
    planted = tmp_path / "planted.py"
    planted.write_text(
        "from btcap.ros.interfaces import _x, y\nfrom btcap import _lazy\n"
        "def f():\n    from .node import _z, __all__\n"
    )
    found = set(_private_imports("btcap.bt.planted", planted))
    assert found == {("btcap.ros.interfaces", "_x"), ("btcap.bt.node", "_z")}
