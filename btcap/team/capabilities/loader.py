"""Resolve the ``"package.module:function"`` references that specs and capability files name.

One place for the format and its error messages, so a launch spec's ``factory`` and an
implementation file's ``bid`` fail the same way.
"""

from __future__ import annotations

import pkgutil
from collections.abc import Callable
from typing import Any

__all__ = ["load_callable"]


def load_callable(ref: str) -> Callable[..., Any]:
    """The callable ``ref`` names (``"package.module:function"``, or ``:Class.method``).

    Raises ValueError saying what is wrong: the format, the import or the attribute; the
    caller prefixes the file or field it came from.
    """
    module, sep, attr = ref.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"{ref!r}: expected 'package.module:function'")
    try:
        obj = pkgutil.resolve_name(ref)
    except ImportError as exc:
        raise ValueError(f"{ref!r}: cannot import {module!r} ({exc})") from None
    except AttributeError:
        raise ValueError(f"{ref!r}: module {module!r} has no attribute {attr!r}") from None
    if not callable(obj):
        raise ValueError(f"{ref!r}: {attr!r} is not callable")
    return obj  # type: ignore[no-any-return]
