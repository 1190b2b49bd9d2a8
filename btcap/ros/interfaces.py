"""ROS 2 interfaces by type name: the class behind ``test_msgs/action/Fibonacci``, the
port types of its fields, and messages filled from / turned into plain values.

Any interface installed where rclpy is works by name (``nav2_msgs/action/NavigateToPose``
wherever nav2_msgs is installed): nothing here is generated per interface. Messages go
to ports as plain values (numbers, strings, lists, dicts for nested messages), so outputs
survive the codec when a capability runs on another robot. Errors are one line, naming the
interface and the field.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Mapping
from typing import Any

import msgspec

from btcap.ros.errors import RosError
from btcap.ros.loader import load

__all__ = ["check_field", "field_types", "fill", "interface", "port_type", "to_plain"]

_KINDS = ("msg", "srv", "action")
_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/(msg|srv|action)/([A-Za-z][A-Za-z0-9_]*)$")
_SHORT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/([A-Za-z][A-Za-z0-9_]*)$")

_INTS = {"byte", "char", "octet"} | {f"{s}int{n}" for s in ("", "u") for n in (8, 16, 32, 64)}
_FLOATS = {"float", "double", "float32", "float64", "long double"}
_SCALARS: dict[str, Any] = {
    **dict.fromkeys(_INTS, int),
    **dict.fromkeys(_FLOATS, float),
    "boolean": bool,
    "bool": bool,
}
_SEQUENCE = re.compile(r"^sequence<(.+?)(?:,\s*\d+)?>$")
_ARRAY = re.compile(r"^(.+?)\[(\d*)\]$")
_STRING = re.compile(r"^w?string(?:<=\d+)?$")


def interface(type_name: str, kind: str) -> Any:
    """The class of ``pkg/kind/Name`` (``pkg/Name`` is taken as that kind), loading rclpy;
    RosError naming the type and what is wrong."""
    load()
    m = _NAME.match(type_name)
    if m is None and (s := _SHORT.match(type_name)) is not None:
        m = _NAME.match(f"{s[1]}/{kind}/{s[2]}")
    if m is None:
        raise RosError(
            f"ROS interface type {type_name!r}: expected 'package/{kind}/Name' "
            f"(e.g. 'test_msgs/{kind}/...')"
        )
    package, got, name = m.groups()
    if got != kind:
        raise RosError(f"ROS interface type {type_name!r}: expected a {kind}, not a {got}")
    try:
        module = importlib.import_module(f"{package}.{got}")
    except ImportError:
        raise RosError(
            f"ROS interface type {type_name!r}: no package {package!r} with {got} "
            "interfaces is installed where rclpy is"
        ) from None
    cls = getattr(module, name, None)
    if cls is None:
        known = sorted(n for n in dir(module) if n[:1].isupper() and not n.startswith("_"))
        raise RosError(
            f"ROS interface type {type_name!r}: {package} has no {got} {name!r}; "
            f"it has {', '.join(known) or 'none'}"
        )
    return cls


def field_types(msg_cls: Any) -> dict[str, str]:
    """Field name -> ROS type text (``int32``, ``sequence<double>``, ``std_msgs/Header``)."""
    types: dict[str, str] = msg_cls.get_fields_and_field_types()
    return types


def port_type(ros_type: str) -> Any:
    """The port type of a field: int, float, bool, str, list[...] or dict for a message."""
    if (m := _SEQUENCE.match(ros_type)) or (m := _ARRAY.match(ros_type)):
        inner = port_type(m[1])
        return list[inner]  # type: ignore[valid-type]
    if _STRING.match(ros_type):
        return str
    scalar = _SCALARS.get(ros_type)
    if scalar is not None:
        return scalar
    return dict[str, Any]


def _int_bounds(ros_type: str) -> tuple[int, int] | None:
    if ros_type in ("byte", "char", "octet"):
        return (0, 255)
    m = re.fullmatch(r"(u?)int(8|16|32|64)", ros_type)
    if m is None:
        return None
    bits = int(m[2])
    return (0, 2**bits - 1) if m[1] else (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)


def check_field(value: Any, ros_type: str, where: str) -> Any:
    """``value`` as field type ``ros_type`` wants it (an int where a float is wanted
    becomes a float); RosError naming ``where`` when it does not fit. rclpy checks field
    types only with ROS_PYTHON_CHECK_FIELDS, and a wrong one fails deep in C otherwise."""
    kind = port_type(ros_type)
    if kind is dict[str, Any] or (
        isinstance(value, list) and value and isinstance(value[0], Mapping)
    ):
        return value
    try:
        out = msgspec.convert(value, kind, strict=True)
    except msgspec.ValidationError as exc:
        raise RosError(f"{where}: {value!r} does not fit {ros_type} ({exc})") from None
    bounds = _int_bounds(ros_type)
    if bounds is not None and not bounds[0] <= out <= bounds[1]:
        raise RosError(f"{where}: {value!r} is out of {ros_type}'s range {bounds[0]}..{bounds[1]}")
    return out


def fill(msg_cls: Any, values: Mapping[str, Any], where: str) -> Any:
    """A ``msg_cls`` with ``values`` set (nested messages from dicts); RosError naming
    ``where`` and the field when a name or value does not fit."""
    msg = msg_cls()
    types = field_types(msg_cls)
    for key, value in values.items():
        if value is None:
            continue
        if key not in types:
            raise RosError(f"{where}: no field {key!r}; fields: {', '.join(types) or 'none'}")
        value = check_field(value, types[key], f"{where}.{key}")
        try:
            setattr(msg, key, _value(getattr(msg, key), types[key], value, f"{where}.{key}"))
        except (AssertionError, TypeError, ValueError) as exc:
            if isinstance(exc, RosError):
                raise
            raise RosError(
                f"{where}.{key}: {value!r} does not fit {types[key]} ({_reason(exc)})"
            ) from None
    return msg


def _value(current: Any, ros_type: str, value: Any, where: str) -> Any:
    if isinstance(value, Mapping) and hasattr(current, "get_fields_and_field_types"):
        return fill(type(current), value, where)
    if isinstance(value, list) and value and isinstance(value[0], Mapping):
        m = _SEQUENCE.match(ros_type) or _ARRAY.match(ros_type)
        if m is not None and "/" in m[1]:
            cls = interface(m[1], "msg")
            return [fill(cls, v, f"{where}[{i}]") for i, v in enumerate(value)]
    return value


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def to_plain(value: Any) -> Any:
    """A message (or field value) as plain data: dicts, lists, numbers, strings."""
    fields = getattr(value, "get_fields_and_field_types", None)
    if fields is not None:
        return {key: to_plain(getattr(value, key)) for key in fields()}
    if isinstance(value, str | bytes | int | float | bool) or value is None:
        return value
    tolist = getattr(value, "tolist", None)  # array.array, numpy arrays
    if tolist is not None:
        return [to_plain(v) for v in tolist()]
    if isinstance(value, list | tuple):
        return [to_plain(v) for v in value]
    return value
