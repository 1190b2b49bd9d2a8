"""Type names in tree files: ``"list[float]"``, ``"dict[str, int] | None"`` to a type and
back, over a table of names (a :class:`~btcap.bt.registry.NodeRegistry`'s), without eval."""

from __future__ import annotations

import re
import types
import typing
from collections.abc import Mapping
from typing import Any

from btcap.bt.spelling import did_you_mean
from btcap.bt.state import RegistryError

__all__ = ["BUILTIN_TYPES", "GENERICS", "format_type", "parse_type"]

#: The names every registry knows.
BUILTIN_TYPES: dict[str, Any] = {
    "Any": Any,
    "None": None,
    "bool": bool,
    "bytes": bytes,
    "dict": dict,
    "float": float,
    "frozenset": frozenset,
    "int": int,
    "list": list,
    "object": object,
    "set": set,
    "str": str,
    "tuple": tuple,
}

#: Generic containers and how many type arguments they take (``None``: tuple's rules).
GENERICS: dict[Any, int | None] = {
    list: 1,
    set: 1,
    frozenset: 1,
    dict: 2,
    tuple: None,
}

_TOKEN = re.compile(r"\s*(?:(\.\.\.)|([A-Za-z_][A-Za-z0-9_.]*)|(\S))")


def parse_type(text: str, names: Mapping[str, Any]) -> Any:
    """Turn ``"dict[str, list[float]] | None"`` into the type, reading ``names``."""
    return _Parser(text, names).parse()


def format_type(tp: Any, names: Mapping[str, Any]) -> str:
    """The inverse of :func:`parse_type`; raises RegistryError for unnamed types."""
    if tp is Any:
        return "Any"
    if tp is None or tp is type(None):
        return "None"
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return " | ".join(format_type(a, names) for a in typing.get_args(tp))
    if origin is not None and origin in GENERICS:
        args = typing.get_args(tp)
        inner = ", ".join("..." if a is Ellipsis else format_type(a, names) for a in args)
        return f"{format_type(origin, names)}[{inner}]" if args else format_type(origin, names)
    for name, known in names.items():
        if known is tp and name != "None":
            return name
    raise RegistryError(
        f"type {tp!r} has no name in files; register it with "
        f"registry.register_type('{getattr(tp, '__name__', 'Name')}', ...)"
    )


class _Parser:
    """Recursive descent over ``union := term ('|' term)*``, ``term := NAME ['[' args ']']``."""

    def __init__(self, text: str, names: Mapping[str, Any]) -> None:
        self.text = text
        self.names = names
        self.tokens = self._tokenize(text)
        self.pos = 0

    def _tokenize(self, text: str) -> list[str]:
        out: list[str] = []
        for m in _TOKEN.finditer(text):
            tok = m.group(1) or m.group(2) or m.group(3)
            if tok is None:
                continue  # trailing whitespace
            if m.group(3) is not None and tok not in "[],|":
                self._fail(f"unexpected character {tok!r}")
            out.append(tok)
        return out

    def _fail(self, why: str) -> typing.NoReturn:
        raise RegistryError(
            f"type {self.text!r}: {why}; expected e.g. 'float', 'list[int]', "
            f"'tuple[float, float]', 'dict[str, int]' or 'int | None'"
        )

    def _peek(self) -> str | None:
        return self.tokens[self.pos] if self.pos < len(self.tokens) else None

    def _take(self, want: str | None = None) -> str:
        tok = self._peek()
        if tok is None:
            self._fail("unexpected end" + (f", expected {want!r}" if want else ""))
        if want is not None and tok != want:
            self._fail(f"expected {want!r}, found {tok!r}")
        self.pos += 1
        return tok

    def parse(self) -> Any:
        if not self.tokens:
            self._fail("empty type name")
        tp = self._union()
        if self._peek() is not None:
            self._fail(f"unexpected {self._peek()!r}")
        return tp

    def _union(self) -> Any:
        members = [self._term()]
        while self._peek() == "|":
            self._take("|")
            members.append(self._term())
        if len(members) == 1:
            return members[0]
        return typing.Union[tuple(members)]  # noqa: UP007 - built at run time

    def _term(self) -> Any:
        tok = self._take()
        if tok in "[],|" or tok == "...":
            self._fail(f"expected a type name, found {tok!r}")
        if tok not in self.names:
            self._fail(f"unknown name {tok!r}{did_you_mean(tok, self.names)}")
        base = self.names[tok]
        if self._peek() != "[":
            return type(None) if base is None else base
        if base not in GENERICS:
            self._fail(f"{tok!r} takes no type arguments")
        self._take("[")
        args: list[Any] = [self._arg(base)]
        while self._peek() == ",":
            self._take(",")
            args.append(self._arg(base))
        self._take("]")
        want = GENERICS[base]
        if want is not None and len(args) != want:
            self._fail(f"{tok}[...] takes {want} type argument(s), got {len(args)}")
        if base is tuple and Ellipsis in args and (len(args) != 2 or args[0] is Ellipsis):
            self._fail("'...' only fits as tuple[X, ...]")
        return base[tuple(args)] if len(args) > 1 else base[args[0]]

    def _arg(self, base: Any) -> Any:
        if self._peek() == "...":
            if base is not tuple:
                self._fail("'...' only fits as tuple[X, ...]")
            self._take()
            return Ellipsis
        return self._union()
