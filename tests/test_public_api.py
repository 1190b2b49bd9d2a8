"""The public API: every exported name resolves, lazily, to what type checkers see."""

from __future__ import annotations

import ast
import importlib
import inspect

import pytest

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
