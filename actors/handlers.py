"""Which method of an actor handles which message: the ``@handler`` mark and the table
read from it, per class, on its first message (when forward references resolve)."""

from __future__ import annotations

import inspect
import types as types_mod
import typing
from collections.abc import Callable
from typing import Any, TypeVar, overload

__all__ = ["Handler", "collect_handlers", "handler"]

F = TypeVar("F", bound=Callable[..., Any])

_HANDLER_ATTR = "__actor_handles__"
_LOCAL_ONLY_ATTR = "__actor_local_only__"


@overload
def handler(fn: F, /) -> F: ...
@overload
def handler(*types: type[Any], local_only: bool = False) -> Callable[[F], F]: ...
def handler(*args: Any, local_only: bool = False) -> Any:
    """Mark a method as the handler of a message type.

    Use bare (the type is read from the annotation of the message parameter) or with the
    types it handles: ``@handler(Ping, Pong)``. Handlers may be sync or async; what they
    return is the reply to an ask.

    ``local_only=True`` takes the message only from inside the actor's own system (its
    actors, tasks and callers); the same message from a transport is refused, counted in
    ``SystemStats.refused`` and answered with :class:`~btcap.actors.errors.Refused`,
    whatever sender it names. For actions no peer has a right to (a BT node's tick).
    """
    bare = len(args) == 1 and inspect.isfunction(args[0])
    types = () if bare else args

    def mark(fn: F) -> F:
        setattr(fn, _HANDLER_ATTR, types)
        if local_only:
            setattr(fn, _LOCAL_ONLY_ATTR, True)
        return fn

    return mark(args[0]) if bare else mark


class Handler:
    """A handler method, with what delivery asks of it on every message."""

    __slots__ = ("fn", "is_async", "local_only")

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.fn = fn
        self.is_async = inspect.iscoroutinefunction(fn)
        self.local_only: bool = getattr(fn, _LOCAL_ONLY_ATTR, False)


def collect_handlers(cls: type[Any]) -> dict[type[Any], Handler]:
    """The handler of each message type an actor class ``cls`` and its bases declare (a
    subclass's wins)."""
    table: dict[type[Any], Handler] = {}
    for klass in reversed(cls.__mro__):
        for name, fn in vars(klass).items():
            declared = getattr(fn, _HANDLER_ATTR, None)
            if declared is None:
                continue
            types = declared
            if not types:
                hints = typing.get_type_hints(fn)
                params = [p for p in inspect.signature(fn).parameters if p != "self"]
                if not params or params[0] not in hints:
                    raise TypeError(
                        f"{cls.__qualname__}.{name}: annotate the message parameter or "
                        f"name the types in @handler(...)"
                    )
                hint = hints[params[0]]
                union = typing.get_origin(hint) in (typing.Union, types_mod.UnionType)
                types = typing.get_args(hint) if union else (hint,)
            for t in types:
                table[t] = Handler(fn)
    return table
