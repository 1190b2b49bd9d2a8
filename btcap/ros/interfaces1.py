"""ROS 1 interfaces by type name: the genpy classes behind ``move_base_msgs/MoveBase``
(an action), ``std_srvs/SetBool`` (a service) or ``geometry_msgs/PoseStamped`` (a
message), the port types of their fields, and messages filled from / turned into plain
values, as :mod:`btcap.ros.interfaces` does for ROS 2 (issue #34's first backend piece).

Names are ROS 1's ``package/Name``; ROS 2's ``package/kind/Name`` is taken too, so one tree
file names an interface the same way for either version. An action ``pkg/Name`` is
actionlib's generated ``NameAction`` with ``NameGoal``, ``NameResult`` and ``NameFeedback``
in ``pkg.msg``. Port types and value checks are :mod:`btcap.ros.interfaces`' own (the field
type text of both versions share their syntax: ``float64[36]``, ``string``, ``pkg/Msg``);
only ROS 1's ``time`` and ``duration`` and its byte arrays differ. Importing this module
imports nothing of ROS; the lookups import the message packages where rospy is.
"""

from __future__ import annotations

import importlib
import io
import re
from collections.abc import Mapping
from typing import Any, NamedTuple

from btcap.ros.errors import RosError
from btcap.ros.interfaces import array_shape, check_field, kind_name, port_type

__all__ = ["Action1", "Service1", "field_types1", "fill1", "interface1", "port_type1", "to_plain1"]

_NAME = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)/(?:(msg|srv|action)/)?([A-Za-z][A-Za-z0-9_]*)$")
_TIMES = ("time", "duration")
#: Arrays genpy holds as bytes (ROS 1's ``byte[]`` is a list of int8).
_BYTES = re.compile(r"^(uint8|char)\[\d*\]$")
_ALIASES = {"byte": "int8", "char": "uint8"}


class Action1(NamedTuple):
    """An actionlib action: its ``Action`` class (what ``SimpleActionClient`` takes) and
    the Goal, Result and Feedback messages."""

    Action: Any
    Goal: Any
    Result: Any
    Feedback: Any


class Service1(NamedTuple):
    """A ROS 1 service: its class (what ``ServiceProxy`` takes), Request and Response."""

    Service: Any
    Request: Any
    Response: Any


def interface1(type_name: str, kind: str) -> Any:
    """The genpy class(es) of ``type_name`` of ``kind`` (``msg``, ``srv``, ``action``):
    a message class, a :class:`Service1` or an :class:`Action1`; RosError naming the type
    and what is wrong."""
    m = _NAME.match(type_name)
    if m is None:
        raise RosError(
            f"ROS 1 interface type {type_name!r}: expected 'package/Name' "
            f"(e.g. 'std_msgs/String') or 'package/{kind}/Name'"
        )
    package, got, name = m[1], m[2] or kind, m[3]
    if got != kind:
        raise RosError(
            f"ROS 1 interface type {type_name!r}: expected {kind_name(kind)}, not {kind_name(got)}"
        )
    where = "srv" if kind == "srv" else "msg"
    try:
        module = importlib.import_module(f"{package}.{where}")
    except ImportError:
        raise RosError(
            f"ROS 1 interface type {type_name!r}: no package {package!r} with {where} "
            "types is installed where rospy is"
        ) from None
    if kind == "action":
        parts = [
            getattr(module, f"{name}{p}", None) for p in ("Action", "Goal", "Result", "Feedback")
        ]
        if any(p is None for p in parts):
            known = sorted(n[: -len("Action")] for n in dir(module) if n.endswith("Action"))
            raise RosError(
                f"ROS 1 interface type {type_name!r}: {package} has no action {name!r}; "
                f"it has {', '.join(known) or 'none'}"
            )
        return Action1(*parts)
    cls = getattr(module, name, None)
    if cls is None or (kind == "msg" and not hasattr(cls, "_slot_types")):
        known = sorted(
            n for n in dir(module) if n[:1].isupper() and not n.endswith(("Request", "Response"))
        )
        raise RosError(
            f"ROS 1 interface type {type_name!r}: {package} has no {where} {name!r}; "
            f"it has {', '.join(known) or 'none'}"
        )
    if kind == "srv":
        return Service1(cls, cls._request_class, cls._response_class)
    return cls


def field_types1(msg_cls: Any) -> dict[str, str]:
    """Field name -> ROS 1 type text (``int32``, ``float64[36]``, ``std_msgs/Header``)."""
    return dict(zip(msg_cls.__slots__, msg_cls._slot_types, strict=True))


def port_type1(ros_type: str) -> Any:
    """The port type of a ROS 1 field; ``time`` and ``duration`` are ``{secs, nsecs}``."""
    if ros_type in _TIMES:
        return dict[str, Any]
    return port_type(ros_type)


def _is_message(value: Any) -> bool:
    return hasattr(value, "_slot_types")


def to_plain1(value: Any) -> Any:
    """A genpy message (or field value) as plain data: dicts, lists, numbers, strings; a
    byte array as a list of ints, a time or duration as ``{secs, nsecs}``."""
    if _is_message(value):
        return {key: to_plain1(getattr(value, key)) for key in value.__slots__}
    if hasattr(value, "secs") and hasattr(value, "nsecs"):  # genpy.Time / Duration
        return {"secs": int(value.secs), "nsecs": int(value.nsecs)}
    if isinstance(value, bytes):
        return list(value)
    if isinstance(value, list | tuple):
        return [to_plain1(v) for v in value]
    return value


def fill1(msg_cls: Any, values: Mapping[str, Any], where: str) -> Any:
    """A ``msg_cls`` with ``values`` set (nested messages from dicts); RosError naming
    ``where`` and the field when a name or value does not fit. The message is serialized
    once here, so what genpy would refuse on the wire (a fixed array's length) is refused
    now, naming ``where``, not on rospy's thread."""
    msg = _fill(msg_cls, values, where)
    try:
        msg.serialize(io.BytesIO())
    except Exception as exc:  # genpy.SerializationError, struct.error, ...
        text = str(exc).strip().splitlines()
        raise RosError(f"{where}: {text[0] if text else type(exc).__name__}") from None
    return msg


def _fill(msg_cls: Any, values: Mapping[str, Any], where: str) -> Any:
    msg = msg_cls()
    types = field_types1(msg_cls)
    for key, value in values.items():
        if value is None:
            continue
        if key not in types:
            raise RosError(f"{where}: no field {key!r}; fields: {', '.join(types) or 'none'}")
        setattr(msg, key, _value(getattr(msg, key), types[key], value, f"{where}.{key}"))
    return msg


def _value(current: Any, ros_type: str, value: Any, where: str) -> Any:
    if ros_type in _TIMES:
        return _time(type(current), ros_type, value, where)
    if _is_message(current):
        if not isinstance(value, Mapping):
            raise RosError(f"{where}: {value!r} does not fit {ros_type}: expected a mapping")
        return _fill(type(current), value, where)
    shape = array_shape(ros_type)
    if shape is not None and "/" in shape[0] and isinstance(value, list | tuple):
        check_field(value, ros_type, where)  # its length, and each item a message's fields
        cls = interface1(shape[0], "msg")
        return [
            v if _is_message(v) else _fill(cls, v, f"{where}[{i}]") for i, v in enumerate(value)
        ]
    if shape is not None and shape[0] in _TIMES and isinstance(value, list | tuple):
        import genpy

        kind = genpy.Time if shape[0] == "time" else genpy.Duration
        check_field([0] * len(value), f"int32{ros_type[len(shape[0]) :]}", where)  # length
        return [_time(kind, shape[0], v, f"{where}[{i}]") for i, v in enumerate(value)]
    value = check_field(value, _as_checked(ros_type), where)
    if _BYTES.match(ros_type):  # genpy holds uint8[] / char[] as bytes
        return bytes(value)
    return value


def _as_checked(ros_type: str) -> str:
    """A ROS 1 field type as :func:`check_field` reads it: ROS 1's ``byte`` is a signed
    int8 and its ``char`` an unsigned uint8 (ROS 2 has them the other way round)."""
    base, bracket, rest = ros_type.partition("[")
    base = _ALIASES.get(base, base)
    return f"{base}{bracket}{rest}"


def _time(kind: Any, ros_type: str, value: Any, where: str) -> Any:
    """A genpy Time (``secs``, ``nsecs``: uint32) or Duration (int32) from ``{secs,
    nsecs}``."""
    if not isinstance(value, Mapping) or set(value) - {"secs", "nsecs"}:
        raise RosError(f"{where}: {value!r} does not fit {ros_type}: expected {{secs, nsecs}}")
    part = "uint32" if ros_type == "time" else "int32"
    secs = check_field(value.get("secs", 0), part, f"{where}.secs")
    nsecs = check_field(value.get("nsecs", 0), part, f"{where}.nsecs")
    made = kind(secs, nsecs)  # normalized: nsecs over a second carry into secs
    if ros_type == "time" and made.secs > 2**32 - 1:
        raise RosError(f"{where}: {value!r} is past time's last second, {2**32 - 1}")
    return made
