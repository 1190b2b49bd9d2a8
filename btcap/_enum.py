"""An Enum metaclass whose ``Member.X`` reads cost what a plain class attribute costs.

On CPython 3.11 ``enum.EnumType`` defines ``__getattr__``, and a metaclass that does
sends every class attribute read through a Python-level call of
``type.__getattribute__``: ``State.SUCCEEDED`` or ``Kind.ASK`` cost ~70 ns (~850
instructions), ten times a module constant, on hot paths (every tick, every envelope).
With ``object.__getattribute__`` the interpreter reads the class's own dict in C, where
the members live; anything else (inherited methods) falls back to the full lookup. An
own-dict value must then read the same either way, which ``__init__`` checks. Python
3.12 dropped ``EnumType.__getattr__``; there this class changes nothing.
"""

from __future__ import annotations

import enum
import sys
from typing import Any

__all__ = ["FastEnumType"]


class FastEnumType(enum.EnumType):
    """``metaclass=FastEnumType`` on an Enum makes its member reads cheap on 3.11."""

    if sys.version_info < (3, 12):
        __getattribute__ = object.__getattribute__

        def __getattr__(cls, name: str) -> Any:
            return type.__getattribute__(cls, name)

        def __init__(cls, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            for key, value in vars(cls).items():
                get = getattr(type(value), "__get__", None)
                if get is None:
                    continue
                try:
                    same = get(value, None, cls) is value
                except Exception:  # a descriptor that refuses a class-level read
                    same = False
                if not same:
                    raise TypeError(f"{cls.__name__}.{key}: reads differently from the class")
