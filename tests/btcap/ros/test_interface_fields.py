"""ROS 2 field kinds beyond plain scalars, as real interfaces have them: bounded strings,
bounded and fixed-size arrays, bytes, nested messages in arrays, header stamps. Filled
from plain values, read back as plain values that fill the same message again, and a
value that does not fit is one line naming the field (rclpy itself would fail deep in C,
or send a wrong message)."""

from __future__ import annotations

from typing import Any

import msgspec
import pytest

from btcap.ros.errors import RosError
from btcap.ros.interfaces import field_types, fill, interface, port_type, to_plain

pytestmark = pytest.mark.ros


def _serialized(msg: Any) -> Any:
    from rclpy.serialization import deserialize_message, serialize_message

    return deserialize_message(serialize_message(msg), type(msg))


@pytest.mark.parametrize(
    "type_name",
    [
        "test_msgs/msg/Arrays",
        "test_msgs/msg/BoundedSequences",
        "test_msgs/msg/UnboundedSequences",
        "test_msgs/msg/BasicTypes",
        "test_msgs/msg/Strings",
        "test_msgs/msg/WStrings",
        "test_msgs/msg/MultiNested",
        "nav_msgs/msg/Path",
    ],
)
def test_a_message_read_as_plain_values_fits_its_ports_and_fills_it_again(type_name: str) -> None:
    cls = interface(type_name, "msg")
    types = field_types(cls)
    plain = to_plain(cls())
    for key, value in plain.items():
        msgspec.convert(value, port_type(types[key]))  # the output port's type
    again = fill(cls, plain, "msg")
    assert to_plain(_serialized(again)) == plain


def test_bytes_are_ints_both_ways() -> None:
    cls = interface("test_msgs/msg/UnboundedSequences", "msg")
    msg = fill(cls, {"byte_values": [1, 255], "uint8_values": [7]}, "msg")
    back = to_plain(_serialized(msg))
    assert back["byte_values"] == [1, 255]
    basic_types = interface("test_msgs/BasicTypes", "msg")
    basic = to_plain(_serialized(fill(basic_types, {"byte_value": 9}, "m")))
    assert basic["byte_value"] == 9


def test_bounded_strings_take_strings_up_to_their_bound() -> None:
    cls = interface("test_msgs/msg/Strings", "msg")
    assert field_types(cls)["bounded_string_value"] == "string<22>"
    assert port_type("string<22>") is str
    assert (
        to_plain(_serialized(fill(cls, {"bounded_string_value": "husky"}, "m")))[
            "bounded_string_value"
        ]
        == "husky"
    )
    too_long = r"^m\.bounded_string_value: 'x{30}' is longer than string<22>'s 22 characters$"
    with pytest.raises(RosError, match=too_long):
        fill(cls, {"bounded_string_value": "x" * 30}, "m")


@pytest.mark.parametrize(
    ("type_name", "values", "why"),
    [
        (
            "test_msgs/msg/BoundedSequences",
            {"int32_values": [1, 2, 3, 4]},
            r"^goal\.int32_values: 4 items do not fit sequence<int32, 3> \(at most 3\)$",
        ),
        (
            "test_msgs/msg/Arrays",
            {"int32_values": [1, 2]},
            r"^goal\.int32_values: 2 items do not fit int32\[3\] \(exactly 3\)$",
        ),
        (
            "test_msgs/msg/UnboundedSequences",
            {"uint8_values": [1, 300]},
            r"^goal\.uint8_values\[1\]: 300 is out of uint8's range 0\.\.255$",
        ),
        (
            "test_msgs/msg/UnboundedSequences",
            {"byte_values": [256]},
            r"^goal\.byte_values\[0\]: 256 is out of octet's range 0\.\.255$",
        ),
        (
            "nav_msgs/msg/Path",
            {"poses": [{"header": {"stamp": {"sec": 1}}}, {"header": {"stamp": {"sec": -1.5}}}]},
            r"^goal\.poses\[1\]\.header\.stamp\.sec: -1\.5 does not fit int32",
        ),
        (
            "test_msgs/msg/UnboundedSequences",
            {"float32_values": [1.0, float("inf"), 1e40]},
            r"^goal\.float32_values\[2\]: 1e\+40 is out of float's range ",
        ),
        (
            "test_msgs/msg/BasicTypes",
            {"float32_value": -1e39},
            r"^goal\.float32_value: -1e\+39 is out of float's range ",
        ),
        (
            "nav_msgs/msg/Path",
            {"poses": [{"pose": {}}, 3]},
            r"^goal\.poses\[1\]: 3 does not fit geometry_msgs/PoseStamped",
        ),
    ],
)
def test_a_value_that_does_not_fit_is_one_line_naming_the_field(
    type_name: str, values: dict[str, Any], why: str
) -> None:
    with pytest.raises(RosError, match=why) as err:
        fill(interface(type_name, "msg"), values, "goal")
    assert "\n" not in str(err.value)
