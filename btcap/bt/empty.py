"""Shared, unwritable empty containers: what a node without ports, options or children
holds instead of empty dicts and lists of its own (a flat tree is mostly such leaves,
and an empty dict or list costs 56-64 bytes a node).

They are a real ``dict``/``list`` to every reader; writing to one raises the error a
write to an undeclared port or a child of a leaf deserves, instead of quietly giving
every node the key.
"""

from __future__ import annotations

from typing import Any, NoReturn

from btcap.bt.state import TreeError

__all__ = ["NO_CHILDREN", "NO_VALUES", "NoChildren", "NoValues"]


def _refuse(what: str) -> NoReturn:
    raise TreeError(what)


class NoValues(dict[str, Any]):
    """The inputs, outputs or options of a node that declares none."""

    __slots__ = ()

    def __setitem__(self, key: str, value: Any) -> None:
        _refuse(f"no port or option {key!r}: the node declares none (see INPUTS/OUTPUTS)")

    def _write(self, *args: Any, **kwargs: Any) -> NoReturn:
        _refuse("the node declares no ports or options to write")

    __delitem__ = update = setdefault = pop = popitem = clear = __ior__ = _write

    def __reduce__(self) -> Any:
        return (dict, ())


class NoChildren(list[Any]):
    """The children of a node that takes none (a leaf)."""

    __slots__ = ()

    def _write(self, *args: Any, **kwargs: Any) -> NoReturn:
        _refuse("a leaf takes no children")

    append = insert = extend = remove = pop = clear = sort = reverse = _write
    __setitem__ = __delitem__ = __iadd__ = __imul__ = _write

    def __reduce__(self) -> Any:
        return (list, ())


NO_VALUES: dict[str, Any] = NoValues()
NO_CHILDREN: list[Any] = NoChildren()
