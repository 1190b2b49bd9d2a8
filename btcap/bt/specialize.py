"""Per-class copies of the node actions on the tick path.

CPython's specialising interpreter keeps its inline caches in the code object: one
``Node.tick`` shared by every node class sees a different ``on_tick`` at each call and
misses. A class that does not write its own action gets a copy of the inherited one,
with a code object of its own, so its caches stay monomorphic.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from types import FunctionType
from typing import Any

__all__ = ["own_copies", "own_copy"]


def own_copy(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` with a code object of its own."""
    copy = FunctionType(fn.__code__.replace(), fn.__globals__, fn.__name__, fn.__defaults__)
    copy.__qualname__, copy.__doc__ = fn.__qualname__, fn.__doc__
    copy.__kwdefaults__, copy.__annotations__ = fn.__kwdefaults__, fn.__annotations__
    return copy


def own_copies(cls: type, base: type, names: Iterable[str]) -> None:
    """Give ``cls`` its own copy of each of ``base``'s methods ``names`` it inherits as is."""
    for name in names:
        fn = base.__dict__[name]
        if name not in cls.__dict__ and getattr(cls, name).__code__ == fn.__code__:
            setattr(cls, name, own_copy(fn))
