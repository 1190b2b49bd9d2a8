"""Per-class copies of the node actions on the tick path.

CPython's specialising interpreter keeps its inline caches in the code object: one
``Node.tick`` shared by every node class sees a different ``on_tick`` at each call and
misses. A class that does not write its own action gets a copy of the inherited one,
with a code object of its own, so its caches stay monomorphic.
"""

from __future__ import annotations

import dis
import enum
import sys
from collections.abc import Callable, Iterable
from types import FunctionType
from typing import Any

__all__ = ["interned_members", "own_copies", "own_copy"]


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


_CPYTHON_311 = sys.implementation.name == "cpython" and sys.version_info[:2] == (3, 11)
_OP = dis.opmap
#: A global load followed by an attribute load: 1 + 5 caches, then 1 + 4 (CPython 3.11).
_SPAN = 2 * (1 + 5 + 1 + 4)


def interned_members(fn: Callable[..., Any], enum_cls: type[enum.Enum]) -> Callable[..., Any]:
    """``fn`` with each ``Enum.MEMBER`` read (``State.SUCCEEDED``) made a constant.

    On CPython 3.11 reading an attribute of a class is never specialised; an Enum member
    read costs ~3x a module constant however fast the metaclass (see
    :class:`btcap.bt.state.State`). A node's ``on_tick`` reading ``State.X``, with
    ``State`` the module global it was defined with, gets the member as a constant
    instead: the bytes of the two loads become ``LOAD_CONST`` and a jump over the rest,
    so offsets, line numbers and the exception table stay as they were. Other Pythons,
    other names and anything unexpected are left alone.
    """
    if not _CPYTHON_311 or not isinstance(fn, FunctionType):
        return fn
    code = fn.__code__
    raw, names, consts = bytearray(code.co_code), code.co_names, list(code.co_consts)
    members = enum_cls.__members__
    changed = False
    for i in range(0, len(raw) - _SPAN + 2, 2):
        if (
            raw[i] != _OP["LOAD_GLOBAL"]
            or raw[i + 1] & 1
            or (i and raw[i - 2] == _OP["EXTENDED_ARG"])
        ):
            continue
        j = i + 12  # the attribute load after the global load's five caches
        if raw[j] != _OP["LOAD_ATTR"] or fn.__globals__.get(names[raw[i + 1] >> 1]) is not enum_cls:
            continue
        member = members.get(names[raw[j + 1]])
        if member is None:
            continue
        index = next((k for k, c in enumerate(consts) if c is member), len(consts))
        if index == len(consts):
            consts.append(member)
        if index > 255:
            continue
        raw[i : i + 4] = bytes((_OP["LOAD_CONST"], index, _OP["JUMP_FORWARD"], _SPAN // 2 - 2))
        changed = True
    if not changed:
        return fn
    new = FunctionType(
        code.replace(co_code=bytes(raw), co_consts=tuple(consts)),
        fn.__globals__,
        fn.__name__,
        fn.__defaults__,
        fn.__closure__,
    )
    new.__qualname__, new.__doc__, new.__module__ = fn.__qualname__, fn.__doc__, fn.__module__
    new.__kwdefaults__, new.__annotations__ = fn.__kwdefaults__, fn.__annotations__
    new.__dict__.update(fn.__dict__)
    return new
