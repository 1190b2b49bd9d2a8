"""ROS 1 interfaces by name: Debian's real genpy message, service and action classes,
their port types, and filling / reading them, with one clear line for bad input."""

from __future__ import annotations

from typing import Any

import pytest

from btcap.ros.errors import RosError
from btcap.ros.interfaces1 import (
    Action1,
    Service1,
    field_types1,
    fill1,
    interface1,
    port_type1,
    to_plain1,
)

pytestmark = pytest.mark.ros1


def test_an_action_is_actionlibs_generated_classes_by_either_spelling() -> None:
    from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseGoal

    action = interface1("move_base_msgs/MoveBase", "action")
    assert isinstance(action, Action1)
    assert (action.Action, action.Goal, action.Feedback) == (
        MoveBaseAction,
        MoveBaseGoal,
        MoveBaseFeedback,
    )
    assert interface1("move_base_msgs/action/MoveBase", "action") == action
    assert field_types1(action.Goal) == {"target_pose": "geometry_msgs/PoseStamped"}


def test_a_service_and_a_message() -> None:
    srv = interface1("std_srvs/SetBool", "srv")
    assert isinstance(srv, Service1)
    assert field_types1(srv.Request) == {"data": "bool"}
    assert field_types1(srv.Response) == {"success": "bool", "message": "string"}
    header = interface1("std_msgs/msg/Header", "msg")
    assert field_types1(header) == {"seq": "uint32", "stamp": "time", "frame_id": "string"}
    assert port_type1("time") == port_type1("std_msgs/Header") == dict[str, Any]
    assert port_type1("float64[36]") == list[float]
    assert port_type1("uint32") is int


def test_a_goal_is_filled_from_plain_values_and_read_back() -> None:
    action = interface1("move_base_msgs/MoveBase", "action")
    values = {
        "target_pose": {
            "header": {"frame_id": "map", "stamp": {"secs": 3, "nsecs": 5}},
            "pose": {"position": {"x": 1, "y": 2.5}, "orientation": {"w": 1.0}},
        }
    }
    goal = fill1(action.Goal, values, "goal")
    assert goal.target_pose.pose.position.x == 1.0
    assert isinstance(goal.target_pose.pose.position.x, float)
    plain = to_plain1(goal)
    assert plain["target_pose"]["header"] == {
        "seq": 0,
        "stamp": {"secs": 3, "nsecs": 5},
        "frame_id": "map",
    }
    assert plain["target_pose"]["pose"]["position"] == {"x": 1.0, "y": 2.5, "z": 0.0}


def test_sequences_of_messages_and_byte_arrays() -> None:
    path = fill1(
        interface1("nav_msgs/Path", "msg"),
        {"poses": [{"pose": {"position": {"x": 1}}}, {"pose": {"position": {"x": 2}}}]},
        "path",
    )
    assert [p.pose.position.x for p in path.poses] == [1.0, 2.0]
    array = fill1(interface1("std_msgs/UInt8MultiArray", "msg"), {"data": [1, 2, 255]}, "a")
    assert array.data == b"\x01\x02\xff"
    assert to_plain1(array)["data"] == [1, 2, 255]
    with pytest.raises(RosError, match=r"^a\.data\[0\]: 256 is out of uint8"):
        fill1(interface1("std_msgs/UInt8MultiArray", "msg"), {"data": [256]}, "a")


@pytest.mark.parametrize(
    ("type_name", "kind", "says"),
    [
        ("no_such_msgs/Thing", "action", "no package 'no_such_msgs' with msg types"),
        ("move_base_msgs/Fly", "action", "move_base_msgs has no action 'Fly'; it has MoveBase"),
        ("std_msgs/Nope", "msg", "std_msgs has no msg 'Nope'; it has Bool, Byte"),
        ("std_srvs/SetBool", "msg", "no package 'std_srvs' with msg types"),
        ("std_srvs/srv/SetBool", "action", "expected an action, not a srv"),
        ("SetBool", "srv", "expected 'package/Name'"),
    ],
)
def test_an_unknown_type_is_one_line_naming_it(type_name: str, kind: str, says: str) -> None:
    with pytest.raises(RosError, match="ROS 1 interface type") as info:
        interface1(type_name, kind)
    assert says in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("values", "says"),
    [
        ({"target": {}}, "goal: no field 'target'; fields: target_pose"),
        ({"target_pose": {"pose": {"position": {"x": "far"}}}}, "goal.target_pose.pose.position.x"),
        ({"target_pose": 3}, "goal.target_pose: 3 does not fit geometry_msgs/PoseStamped"),
        ({"target_pose": {"header": {"seq": -1}}}, "out of uint32's range"),
        ({"target_pose": {"header": {"stamp": 5}}}, "expected {secs, nsecs}"),
    ],
)
def test_wrong_goal_fields_are_one_line_naming_the_field(values: dict, says: str) -> None:
    action = interface1("move_base_msgs/MoveBase", "action")
    with pytest.raises(RosError) as info:
        fill1(action.Goal, values, "goal")
    assert says in str(info.value)
    assert "\n" not in str(info.value)


def test_a_fixed_arrays_length_is_refused_before_the_wire() -> None:
    cls = interface1("geometry_msgs/PoseWithCovariance", "msg")
    with pytest.raises(
        RosError, match=r"^pose\.covariance: 3 items do not fit float64\[36\] \(exactly 36\)$"
    ) as info:
        fill1(cls, {"covariance": [0.0] * 3}, "pose")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("type_name", "values", "says"),
    [
        # out-of-range numbers name the field, down to the element, before genpy's struct
        ("std_msgs/Float32", {"data": 1e40}, "m.data: 1e+40 is out of float32's range"),
        ("std_msgs/Float32MultiArray", {"data": [1.0, -1e40]}, "m.data[1]: -1e+40 is out of"),
        # ROS 1's byte is a signed int8, its char an unsigned uint8
        ("std_msgs/Byte", {"data": 200}, "m.data: 200 is out of int8's range -128..127"),
        ("std_msgs/ByteMultiArray", {"data": [1, 128]}, "m.data[1]: 128 is out of int8's"),
        ("std_msgs/Char", {"data": -1}, "m.data: -1 is out of uint8's range 0..255"),
        # time is uint32 seconds and nanoseconds, duration int32
        ("std_msgs/Header", {"stamp": {"secs": -1}}, "m.stamp.secs: -1 is out of uint32's"),
        ("std_msgs/Time", {"data": {"secs": 2**32 - 1, "nsecs": 10**9}}, "m.data: {'secs'"),
        ("std_msgs/Duration", {"data": {"secs": 2**31}}, "m.data.secs: 2147483648 is out of"),
        # an array of messages: each item named
        ("nav_msgs/Path", {"poses": [{}, 5]}, "m.poses[1]: 5 does not fit geometry_msgs/Pose"),
        ("nav_msgs/Path", {"poses": [{}, {"pose": 1}]}, "m.poses[1].pose: 1 does not fit"),
    ],
)
def test_values_out_of_a_fields_range_are_one_line_naming_it(
    type_name: str, values: dict, says: str
) -> None:
    with pytest.raises(RosError) as info:
        fill1(interface1(type_name, "msg"), values, "m")
    assert str(info.value).startswith(says)
    assert "\n" not in str(info.value)


def test_values_in_range_that_genpy_takes() -> None:
    """What the checks must not refuse: ROS 1's signed bytes, a time past 2038 (uint32),
    negative durations, infinities as float32, a tuple of messages' fields."""
    msg = lambda t, v: to_plain1(fill1(interface1(t, "msg"), v, "m"))  # noqa: E731
    assert msg("std_msgs/Byte", {"data": -5}) == {"data": -5}
    assert msg("std_msgs/ByteMultiArray", {"data": [-128, 127]})["data"] == [-128, 127]
    assert msg("std_msgs/Char", {"data": 255}) == {"data": 255}
    assert msg("std_msgs/Time", {"data": {"secs": 3_000_000_000}})["data"]["secs"] == 3_000_000_000
    assert msg("std_msgs/Duration", {"data": {"secs": -2, "nsecs": 5}}) == {
        "data": {"secs": -2, "nsecs": 5}
    }
    assert msg("std_msgs/Float32", {"data": float("inf")}) == {"data": float("inf")}
    path = msg("nav_msgs/Path", {"poses": ({"pose": {"position": {"x": 1}}},)})
    assert path["poses"][0]["pose"]["position"]["x"] == 1.0


def test_a_fixed_array_of_messages_is_refused_at_another_length() -> None:
    """genpy writes however many items a fixed array of messages has (its reader then
    misreads the rest of the message): the length is checked here."""
    from genpy.dynamic import generate_dynamic

    point = "float64 x\nfloat64 y\nfloat64 z"
    text = f"geometry_msgs/Point[2] corners\n{'=' * 80}\nMSG: geometry_msgs/Point\n{point}\n"
    cls = generate_dynamic("btcap_test/Box", text)["btcap_test/Box"]
    box = fill1(cls, {"corners": [{"x": 1}, {"y": 2}]}, "box")
    assert [c.x for c in box.corners] == [1.0, 0.0]
    with pytest.raises(RosError, match=r"^box\.corners: 3 items do not fit .*\(exactly 2\)$"):
        fill1(cls, {"corners": [{}, {}, {}]}, "box")
