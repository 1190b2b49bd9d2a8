"""Typed ports (inputs, outputs, options) and the type check applied when wiring."""

from __future__ import annotations

import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any

import msgspec

from btcap.bt.state import TreeError

__all__ = [
    "ENTRY",
    "NO_DEFAULT",
    "Missing",
    "Port",
    "PortMap",
    "assignable",
    "bounds",
    "check_options",
    "check_port",
    "check_value",
    "check_wired",
    "normalize_ports",
    "type_name",
    "wire_problem",
]


class _NoDefault:
    __slots__ = ()

    def __repr__(self) -> str:
        return "NO_DEFAULT"


NO_DEFAULT: Any = _NoDefault()


@dataclass(frozen=True, slots=True)
class Port:
    """A declared port: its type (anything msgspec can encode), default and description.

    An input or option without a default is required; an ``Optional`` type gets ``None``
    as its default. ``meta`` constrains the value (``msgspec.Meta(ge=0)``: not negative),
    checked by msgspec wherever the type is: options and constant inputs when a node is
    made or loaded from a file, wired inputs when the node ticks.
    """

    type: Any = Any
    default: Any = NO_DEFAULT
    description: str = ""
    meta: msgspec.Meta | None = None
    #: ``type`` with ``meta`` applied (to the non-None part of an Optional), for msgspec.
    checked: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "checked", _constrained(self.type, self.meta))

    @property
    def required(self) -> bool:
        return self.default is NO_DEFAULT and not _is_optional(self.type)

    def default_value(self) -> Any:
        if self.default is not NO_DEFAULT:
            return self.default
        return None


PortMap = dict[str, Port]


#: The constraint of an input reading a blackboard entry: none, but it puts the input
#: among those a tick checks (for a :class:`Missing` value), values unconverted.
ENTRY = msgspec.Meta()


class Missing:
    """What an input reads from a blackboard entry that was never written."""

    __slots__ = ("key",)

    def __init__(self, key: str) -> None:
        self.key = key

    def __repr__(self) -> str:
        return f"Missing({self.key!r})"


def _constrained(t: Any, meta: msgspec.Meta | None) -> Any:
    if meta is None:
        return t
    if _is_union(t):
        parts = [p if p is type(None) else Annotated[p, meta] for p in typing.get_args(t)]
        return typing.Union[tuple(parts)]  # noqa: UP007 - built from a runtime list
    return Annotated[t, meta]


def bounds(meta: msgspec.Meta) -> str:
    """A Meta's numeric bounds as text: ``>= 0``, ``> 0 and <= 1``."""
    ops = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))
    parts = [f"{op} {getattr(meta, key):g}" for key, op in ops if getattr(meta, key) is not None]
    return " and ".join(parts)


def _is_optional(t: Any) -> bool:
    return _is_union(t) and type(None) in typing.get_args(t)


def _is_union(t: Any) -> bool:
    return typing.get_origin(t) in (typing.Union, types.UnionType)


def type_name(t: Any) -> str:
    """A readable name for error messages."""
    if t is Any:
        return "Any"
    if isinstance(t, type) and not typing.get_args(t):
        return t.__qualname__
    return repr(t).replace("typing.", "")


def normalize_ports(spec: Any, where: str) -> PortMap:
    """Accept ``{"name": type}`` or ``{"name": Port(...)}`` and return a PortMap."""
    if spec is None:
        return {}
    if not isinstance(spec, dict):
        raise TypeError(f"{where}: expected a dict of port name to type or Port")
    out: PortMap = {}
    for name, p in spec.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise TypeError(f"{where}: port name {name!r} is not an identifier")
        out[name] = p if isinstance(p, Port) else Port(p)
    return out


def assignable(src: Any, dst: Any) -> bool:
    """Whether a value typed ``src`` may flow into a port typed ``dst``."""
    if dst is Any or dst is object or src == dst:
        return True
    if src is Any:
        return True  # checked at run time instead
    if _is_union(src):
        return all(assignable(s, dst) for s in typing.get_args(src))
    if _is_union(dst):
        return any(assignable(src, d) for d in typing.get_args(dst))
    if dst is float and src is int:
        return True
    so, do = typing.get_origin(src) or src, typing.get_origin(dst) or dst
    if isinstance(so, type) and isinstance(do, type):
        if not issubclass(so, do):
            return False
        sa, da = typing.get_args(src), typing.get_args(dst)
        if not da:
            return True
        if len(sa) != len(da):
            return False
        return all(assignable(s, d) for s, d in zip(sa, da, strict=True))
    return False


def check_value(value: Any, t: Any, where: str, meta: msgspec.Meta | None = None) -> Any:
    """Validate (and convert, e.g. list -> tuple) a value for a port, or raise TreeError.

    ``meta`` (a port's constraints) is checked too: ``where: must be >= 0, got -5``.
    """
    if t is Any and meta is None:
        return value
    try:
        return msgspec.convert(value, _constrained(t, meta), strict=False)
    except (msgspec.ValidationError, TypeError) as exc:
        if meta is not None:
            try:
                msgspec.convert(value, t, strict=False)
            except (msgspec.ValidationError, TypeError):
                pass  # the type is wrong too: say that
            else:
                rule = bounds(meta) or str(exc)
                raise TreeError(f"{where}: must be {rule}, got {value!r}") from None
        raise TreeError(
            f"{where}: expected {type_name(t)}, got {type(value).__qualname__} {value!r} ({exc})"
        ) from None


def check_port(value: Any, port: Port, where: str) -> Any:
    """:func:`check_value` against a port's type and constraints."""
    if port.checked is Any:
        return value
    try:
        return msgspec.convert(value, port.checked, strict=False)
    except (msgspec.ValidationError, TypeError):
        return check_value(value, port.type, where, port.meta)  # raises, saying why


def check_options(spec: PortMap, given: Mapping[str, Any], node: str, kind: str) -> dict[str, Any]:
    """Node ``node``'s options (of class ``kind``) checked against ``spec``, defaults filled."""
    unknown = set(given) - set(spec)
    if unknown:
        raise TreeError(
            f"node {node!r} ({kind}): unknown option(s) {', '.join(sorted(unknown))}; "
            f"expected {', '.join(sorted(spec)) or 'none'}"
        )
    out: dict[str, Any] = {}
    for key, port in spec.items():
        if key in given:
            out[key] = check_port(given[key], port, f"node {node!r} option {key!r}")
        elif port.required:
            raise TreeError(
                f"node {node!r} ({kind}): option {key!r} ({type_name(port.type)}) is required"
            )
        else:
            out[key] = port.default_value()
    return out


def check_wired(
    inputs: dict[str, Any], checks: tuple[tuple[str, Port], ...], node: str
) -> TreeError | None:
    """Check (and convert) wired input values a port constrains; the first refusal.

    An input reading a blackboard entry never written fails the node if it is required
    (BehaviorTree.CPP's ``getInput`` fails) and gets its default otherwise.
    """
    for key, port in checks:
        value = inputs[key]
        if type(value) is Missing:
            if port.required:
                return TreeError(
                    f"node {node!r} input {key!r}: blackboard entry {{{value.key}}} has "
                    f"no value (nothing wrote it and the application did not set it)"
                )
            inputs[key] = port.default_value()
            continue
        if port.meta is ENTRY:
            continue
        try:
            inputs[key] = check_port(value, port, f"node {node!r} input {key!r}")
        except TreeError as exc:
            return exc
    return None


def wire_problem(src: Any, source_port: str, dst: Any, target_port: str) -> str | None:
    """Why ``src.source_port`` cannot feed ``dst.target_port`` (nodes), or None."""
    out = src.output_ports.get(source_port)
    if out is None:
        have = ", ".join(src.output_ports) or "none"
        return f"{src.path!r} has no output {source_port!r} (outputs: {have})"
    inp = dst.input_ports.get(target_port)
    if inp is None:
        have = ", ".join(dst.input_ports) or "none"
        return f"{dst.path!r} has no input {target_port!r} (inputs: {have})"
    if not assignable(out.type, inp.type):
        return f"output is {type_name(out.type)} but the input expects {type_name(inp.type)}"
    return None
