"""What the loaders of msgspec-typed files (agent files, scenarios, team files) share.

msgspec checks types and the bounds given with ``msgspec.Meta`` and names the field as
``$.timing.tick_hz``; these helpers turn that into the ``FILE: FIELD: problem`` line
every loader prints, and refuse what msgspec lets through: YAML's ``.inf`` and ``.nan``
(a bound like ``gt=0`` refuses ``.nan`` but not ``.inf``).
"""

from __future__ import annotations

import math
import re
from typing import Any

import msgspec
import msgspec.inspect as mi

__all__ = ["field_first", "not_finite"]

_STEP = re.compile(r"\.([^.\[]+)|\[\d+\]")
#: "keepalive_s: must be below lease_s": a ValueError a Struct's ``__post_init__`` raised.
_OWN_FIELD = re.compile(r"([a-z_][a-z0-9_]*): ")


def field_first(message: str, schema: Any = None) -> str:
    """msgspec's "Expected `int`, got `str` - at `$.timing.tick_hz`" as
    "timing.tick_hz: Expected `int`, got `str`", and "keepalive_s: must be below lease_s -
    at `$.timing`" as "timing.keepalive_s: must be below lease_s"; given the ``schema``
    (the type decoded), an invalid choice also lists the valid ones."""
    what, sep, where = message.rpartition(" - at `$")
    if not sep:  # at the top of the file
        what, where = message, ""
    field = where.rstrip("`")
    if schema is not None and what.startswith("Invalid enum value"):
        choices = _choices(mi.type_info(schema), field)
        if choices:
            what += f"; expected one of {', '.join(repr(c) for c in choices)}"
    if schema is not None and what.startswith("Object contains unknown field"):
        known = _at(mi.type_info(schema), field)
        if isinstance(known, mi.StructType):
            what += f"; expected one of {', '.join(f.encode_name for f in known.fields)}"
    field = field.lstrip(".")
    if field and (own := _OWN_FIELD.match(what)):  # a Struct's own check names its field
        field, what = f"{field}.{own[1]}", what[own.end() :]
    return f"{field}: {what}" if field else what


def _choices(info: mi.Type, path: str) -> tuple[Any, ...]:
    """The values of the Literal (or Enum) at ``path`` (``.events[0].kind``) in ``info``."""
    info = _pick(_at(info, path), (mi.LiteralType, mi.EnumType))
    if isinstance(info, mi.LiteralType):
        return info.values
    if isinstance(info, mi.EnumType):
        return tuple(e.value for e in info.cls)
    return ()


def _at(info: mi.Type, path: str) -> mi.Type:
    """The type at ``path`` (``.events[0]``) in ``info`` (a Struct for the path of an object,
    through lists, dicts and ``X | None``), or ``Any`` where the path leads nowhere."""
    for m in _STEP.finditer(path):
        if m.group(1) is None:  # [i]
            info = _pick(info, (mi.ListType,))
            if not isinstance(info, mi.ListType):
                return mi.AnyType()
            info = info.item_type
            continue
        info = _pick(info, (mi.StructType, mi.DictType))
        if isinstance(info, mi.DictType):
            info = info.value_type
            continue
        fields = {f.encode_name: f.type for f in getattr(info, "fields", ())}
        if m.group(1) not in fields:
            return mi.AnyType()
        info = fields[m.group(1)]
    return _pick(info, (mi.StructType, mi.LiteralType, mi.EnumType))


def _pick(info: mi.Type, kinds: tuple[type[mi.Type], ...]) -> mi.Type:
    """The part of ``info`` of one of ``kinds``, through metadata and unions (``X | None``)."""
    if isinstance(info, mi.Metadata):
        return _pick(info.type, kinds)
    if isinstance(info, mi.UnionType):
        for member in info.types:
            found = _pick(member, kinds)
            if isinstance(found, kinds):
                return found
    return info


def not_finite(value: Any, path: str = "") -> tuple[str, str] | None:
    """``(FIELD, "expected a finite number, got inf")`` for the first float anywhere in
    ``value`` (a Struct, list, dict or scalar) that is infinite or NaN, else None."""
    if isinstance(value, float):
        if math.isfinite(value):
            return None
        return path or "$", f"expected a finite number, got {value}"
    items: list[tuple[str, Any]] = []
    if isinstance(value, msgspec.Struct):
        for f in msgspec.structs.fields(value):
            where = f"{path}.{f.encode_name}" if path else f.encode_name
            items.append((where, getattr(value, f.name)))
    elif isinstance(value, list | tuple):
        items = [(f"{path}[{i}]", v) for i, v in enumerate(value)]
    elif isinstance(value, dict):
        items = [(f"{path}.{k}" if path else str(k), v) for k, v in value.items()]
    for where, item in items:
        if (why := not_finite(item, where)) is not None:
            return why
    return None
