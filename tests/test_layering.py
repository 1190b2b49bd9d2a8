"""The layering contract of DESIGN.md, checked over every import statement in the code.

``btcap.errors`` (the errors' base) <- ``transports`` <- ``actors`` <- ``btcap.bt`` <-
``btcap.team`` <- ``btcap`` (its public API and CLI) <- ``sim`` <- ``bench``: a module may
import its own layer and those below, never above; no two modules import each other,
directly or round a longer circle, and that counts imports inside functions and under
``TYPE_CHECKING`` (a circle hidden there is still a circle a reader has to untangle). The
sans-IO allocation core imports no I/O.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "btcap"

#: Lowest first. A module belongs to the longest prefix listed here.
LAYERS = (
    "btcap.errors",
    "btcap.transports",
    "btcap.actors",
    "btcap.bt",
    "btcap.team",
    "btcap",
    "btcap.sim",
    "btcap.bench",
)
#: Top-level names the folders had before they were installed under btcap.
BARE = ("actors", "transports", "sim", "bench")
#: What the sans-IO core may not import: it decides, the shell does the I/O.
IO_MODULES = ("asyncio", "anyio", "zmq", "socket", "selectors", "btcap.actors", "time")
CORE = "btcap.team.core"


def _modules() -> dict[str, Path]:
    found: dict[str, Path] = {}
    paths = [
        Path(folder, file)
        for folder, _dirs, files in os.walk(PACKAGE, followlinks=True)  # btcap/actors -> ...
        for file in files
        if file.endswith(".py")
    ]
    for path in sorted(paths):
        rel = path.relative_to(PACKAGE).with_suffix("")
        parts = ["btcap", *rel.parts]
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


MODULES = _modules()


def _imports(name: str, path: Path) -> set[str]:
    """Every module ``name`` imports, resolved to modules of btcap where it can be."""
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[: len(base) - node.level + (1 if is_pkg else 0)]
                mod = ".".join([*base, node.module] if node.module else base)
            else:
                mod = node.module or ""
            out.add(mod)
            for alias in node.names:  # ``from btcap.bt import composites`` names a module
                if f"{mod}.{alias.name}" in MODULES:
                    out.add(f"{mod}.{alias.name}")
    return out


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


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
    assert {"btcap.team.agent", "btcap.sim.runner", "btcap.bench.tick"} <= MODULES.keys()


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


def test_the_checker_catches_what_it_is_for() -> None:
    """The rules above must be able to fail: a circle and an upward import are seen."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _layer("btcap.actors.system") < _layer("btcap.bt.node") < _layer("btcap.team.agent")
    assert _layer("btcap.team.agent") < _layer("btcap") < _layer("btcap.sim.runner")


#: Modules are kept small enough to read in one sitting.
MAX_LINES = 450


def test_no_module_is_too_long_to_read() -> None:
    long = {
        mod: n
        for mod, path in MODULES.items()
        if (n := len(path.read_text().splitlines())) > MAX_LINES
    }
    assert not long, f"modules over {MAX_LINES} lines: {long}"
