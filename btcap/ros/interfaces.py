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
import math
import re
from collections.abc import Mapping
from typing import Any

import msgspec

from btcap.ros.errors import RosError
from btcap.ros.loader import load

__all__ = [
    "FLOAT32_MAX",
    "array_shape",
    "check_field",
    "field_types",
    "fill",
    "interface",
    "kind_name",
    "port_type",
    "to_plain",
]

_KINDS = ("msg", "srv", "action")
_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/(msg|srv|action)/([A-Za-z][A-Za-z0-9_]*)$")
_SHORT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/([A-Za-z][A-Za-z0-9_]*)$")

_INTS = {"byte", "char", "octet"} | {f"{s}int{n}" for s in ("", "u") for n in (8, 16, 32, 64)}
_FLOATS = {"float", "double", "float32", "float64", "long double"}
#: The largest finite float32, as rosidl bounds it (an infinity is a float32 too).
FLOAT32_MAX = 3.402823466e38
_FLOAT32 = ("float", "float32")
_SCALARS: dict[str, Any] = {
    **dict.fromkeys(_INTS, int),
    **dict.fromkeys(_FLOATS, float),
    "boolean": bool,
    "bool": bool,
}
#: ``sequence<T>``, ``sequence<T, N>`` (at most N); ``T[N]`` (exactly N), ``T[]``, ``T[<=N]``.
#: A message field's port type: its fields.
_MESSAGE = dict[str, Any]
_SEQUENCE = re.compile(r"^sequence<(.+?)(?:,\s*(\d+))?>$")
_ARRAY = re.compile(r"^(.+?)\[(<=)?(\d*)\]$")
#: ``string``, ``wstring``; bounded: ``string<22>`` (rosidl's text), ``string<=22`` (IDL's).
_STRING = re.compile(r"^w?string(?:<=?(\d+)>?)?$")


def kind_name(kind: str) -> str:
    """``an action``, ``a msg``, ``a srv``: for errors."""
    return f"an {kind}" if kind[0] in "aeiou" else f"a {kind}"


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
        raise RosError(
            f"ROS interface type {type_name!r}: expected {kind_name(kind)}, not {kind_name(got)}"
        )
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


def array_shape(ros_type: str) -> tuple[str, int | None, bool] | None:
    """An array field's element type, bound and whether the bound is exact (``T[N]``);
    None for a field that is no array."""
    if (m := _SEQUENCE.match(ros_type)) is not None:
        return m[1], int(m[2]) if m[2] else None, False
    if (m := _ARRAY.match(ros_type)) is not None:
        return m[1], int(m[3]) if m[3] else None, not m[2] and bool(m[3])
    return None


def port_type(ros_type: str) -> Any:
    """The port type of a field: int, float, bool, str, list[...] or dict for a message."""
    if (shape := array_shape(ros_type)) is not None:
        inner = port_type(shape[0])
        return list[inner]  # type: ignore[valid-type]
    if _STRING.match(ros_type):
        return str
    scalar = _SCALARS.get(ros_type)
    if scalar is not None:
        return scalar
    return _MESSAGE


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
    becomes a float); RosError naming ``where`` when it does not fit: its type, an
    integer's range, a bounded string's length, an array's length (exact for ``T[N]``, at
    most N for ``sequence<T, N>``) and each element, named by its index. rclpy checks
    field types only with ROS_PYTHON_CHECK_FIELDS; otherwise a wrong one fails deep in C,
    or goes out wrong (an int in a byte array)."""
    kind = port_type(ros_type)
    if kind == _MESSAGE:
        if isinstance(value, Mapping) or hasattr(value, "get_fields_and_field_types"):
            return value
        if not hasattr(value, "_slot_types"):  # a ROS 1 message is taken as it is
            raise RosError(f"{where}: {value!r} does not fit {ros_type} (expected its fields)")
        return value
    shape = array_shape(ros_type)
    if shape is not None and isinstance(value, list | tuple):
        inner, bound, exact = shape
        if bound is not None and (len(value) != bound if exact else len(value) > bound):
            raise RosError(
                f"{where}: {len(value)} items do not fit {ros_type} "
                f"({'exactly' if exact else 'at most'} {bound})"
            )
        if port_type(inner) == _MESSAGE or _STRING.match(inner):
            return [check_field(v, inner, f"{where}[{i}]") for i, v in enumerate(value)]
    try:
        out = msgspec.convert(value, kind, strict=True)
    except msgspec.ValidationError as exc:
        raise RosError(f"{where}: {value!r} does not fit {ros_type} ({exc})") from None
    if shape is not None:
        bounds = _int_bounds(shape[0])
        if bounds is not None:
            for i, v in enumerate(out):
                if not bounds[0] <= v <= bounds[1]:
                    raise _out_of(v, shape[0], bounds, f"{where}[{i}]")
        elif shape[0] in _FLOAT32:
            for i, v in enumerate(out):
                if abs(v) > FLOAT32_MAX and not math.isinf(v):
                    raise _out_of(v, shape[0], (-FLOAT32_MAX, FLOAT32_MAX), f"{where}[{i}]")
        return out
    bounds = _int_bounds(ros_type)
    if bounds is not None and not bounds[0] <= out <= bounds[1]:
        raise _out_of(value, ros_type, bounds, where)
    if ros_type in _FLOAT32 and abs(out) > FLOAT32_MAX and not math.isinf(out):
        raise _out_of(value, ros_type, (-FLOAT32_MAX, FLOAT32_MAX), where)
    if (m := _STRING.match(ros_type)) is not None and m[1] and len(out) > int(m[1]):
        raise RosError(f"{where}: {value!r} is longer than {ros_type}'s {m[1]} characters")
    return out


def _out_of(value: Any, ros_type: str, bounds: tuple[float, float], where: str) -> RosError:
    return RosError(f"{where}: {value!r} is out of {ros_type}'s range {bounds[0]}..{bounds[1]}")


def fill(msg_cls: Any, values: Mapping[str, Any], where: str) -> Any:
    """A ``msg_cls`` with ``values`` set (nested messages from dicts, also in arrays);
    RosError naming ``where`` and the field when a name or value does not fit."""
    msg = msg_cls()
    types = field_types(msg_cls)
    for key, value in values.items():
        if value is None:
            continue
        if key not in types:
            raise RosError(f"{where}: no field {key!r}; fields: {', '.join(types) or 'none'}")
        here = f"{where}.{key}"
        value = _value(check_field(value, types[key], here), types[key], here)
        try:
            setattr(msg, key, value)
        except (AssertionError, TypeError, ValueError) as exc:
            raise RosError(
                f"{here}: {value!r} does not fit {types[key]} ({_reason(exc)})"
            ) from None
    return msg


def _value(value: Any, ros_type: str, where: str) -> Any:
    """A checked plain value as rosidl holds it: messages from dicts, bytes for octets."""
    if (shape := array_shape(ros_type)) is not None:
        inner = shape[0]
        if inner == "octet":
            return [bytes((v,)) for v in value]
        if "/" in inner:
            return [_value(v, inner, f"{where}[{i}]") for i, v in enumerate(value)]
        return value
    if ros_type == "octet":
        return bytes((value,))
    if isinstance(value, Mapping):
        return fill(interface(ros_type, "msg"), value, where)
    return value


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def to_plain(value: Any) -> Any:
    """A message (or field value) as plain data: dicts, lists, numbers, strings."""
    fields = getattr(value, "get_fields_and_field_types", None)
    if fields is not None:
        return {key: to_plain(getattr(value, key)) for key in fields()}
    if isinstance(value, bytes):  # rosidl's octet: one byte each
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, str | int | float | bool) or value is None:
        return value
    tolist = getattr(value, "tolist", None)  # array.array, numpy arrays
    if tolist is not None:
        return [to_plain(v) for v in tolist()]
    if isinstance(value, list | tuple):
        return [to_plain(v) for v in value]
    return value
