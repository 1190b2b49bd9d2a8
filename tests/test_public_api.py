"""The public API: every exported name resolves, lazily, to what type checkers see."""

from __future__ import annotations

import ast
import importlib
import inspect
from pathlib import Path

import pytest
from btcap_sources import modules

import btcap


@pytest.mark.parametrize("name", sorted(btcap.__all__))
def test_every_exported_name_resolves(name: str) -> None:
    assert getattr(btcap, name) is not None


def test_all_is_unique() -> None:
    assert len(set(btcap.__all__)) == len(btcap.__all__)


def _static_imports(package: str) -> dict[str, str]:
    """Name -> module of the ``if TYPE_CHECKING:`` imports of a package's __init__: what
    type checkers and IDEs see."""
    tree = ast.parse(inspect.getsource(importlib.import_module(package)))
    out: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom)
                assert imp.module
                out.update({alias.name: imp.module for alias in imp.names})
    return out


@pytest.mark.parametrize("package", ["btcap", "btcap.monitor", "btcap.sim", "btcap.transports"])
def test_lazy_exports_are_what_type_checkers_see(package: str) -> None:
    """The names a package imports on first use are exactly its ``__all__`` and exactly
    the names its ``TYPE_CHECKING`` block imports, from the same modules."""
    module = importlib.import_module(package)
    lazy = {name: mod for mod, names in module._EXPORTS.items() for name in names}
    assert lazy == _static_imports(package)
    assert sorted(lazy) == sorted(module.__all__)
    assert set(module.__all__) <= set(dir(module))
    for name in module.__all__:
        assert getattr(module, name) is getattr(importlib.import_module(lazy[name]), name)
    with pytest.raises(AttributeError, match=f"module '{package}' has no attribute 'Nope'"):
        _ = module.Nope


def _declared(path: Path) -> set[str] | None:
    """A module's ``__all__``, or None if it declares none."""
    for node in ast.parse(path.read_text(), str(path)).body:
        target = node.targets[0] if isinstance(node, ast.Assign) else getattr(node, "target", None)
        if isinstance(target, ast.Name) and target.id == "__all__":
            assert isinstance(node, ast.Assign | ast.AnnAssign)
            assert node.value is not None
            return set(ast.literal_eval(node.value))
    return None


def _undeclared(modules: dict[str, Path]) -> list[str]:
    """Each public name a module takes from another of btcap's modules whose ``__all__``
    leaves it out (a submodule named in the import is a module, not a name)."""
    declared = {name: _declared(path) for name, path in modules.items()}
    bad = []
    for name, path in modules.items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom) or node.level or node.module not in modules:
                continue
            exported = declared[node.module]
            for alias in node.names:
                public = not alias.name.startswith("_")
                submodule = f"{node.module}.{alias.name}" in modules
                if exported is not None and public and not submodule and alias.name not in exported:
                    bad.append(f"{name} imports {alias.name} from {node.module}, not in __all__")
    return sorted(bad)


def test_names_shared_across_modules_are_declared() -> None:
    """``__all__`` says what a module offers the others: a name another module imports is
    part of it, so a reader (and ``from m import *``, and the docs) sees every name that
    is depended on, and a name left out is safe to change."""
    assert not _undeclared(modules())


def test_the_declared_check_sees_them(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text('__all__ = ["shown"]\nshown = hidden = 1\n')
    (tmp_path / "b.py").write_text("from pkg.a import shown, hidden, _own\n")
    found = _undeclared({"pkg.a": tmp_path / "a.py", "pkg.b": tmp_path / "b.py"})
    assert found == ["pkg.b imports hidden from pkg.a, not in __all__"]
