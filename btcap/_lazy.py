"""Lazy re-exports for package ``__init__`` modules (PEP 562).

A package lists what it re-exports by module; nothing is imported until a name is
first used, so ``import btcap`` (and ``btcap --help``) stay fast, and a program that
never touches the monitor or the simulation never pays for aiohttp, scipy or numpy.
Type checkers see the same names through the package's ``if TYPE_CHECKING:`` imports.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, exports: Mapping[str, Sequence[str]]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package``, which re-exports ``names``
    of each ``module`` in ``exports``; a name is imported on first use, then cached in
    the package's namespace (later uses cost nothing)."""
    where = {name: module for module, names in exports.items() for name in names}
    namespace = vars(sys.modules[package])

    def __getattr__(name: str) -> object:  # noqa: N807 (the name PEP 562 asks for)
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:  # noqa: N807
        return sorted({*namespace, *where})

    return __getattr__, __dir__
