"""Names in the robot's namespace, without ROS: a private name (``~``) is in the node's own
namespace, written as ROS 1 writes it (``~foo``) or as ROS 2 does (``~/foo``), for either
bridge; ``~foo`` had become ``/husky1/btcapfoo``."""

from __future__ import annotations

import pytest

from btcap.ros.client import RosBridge
from btcap.ros.client1 import Ros1Bridge
from btcap.team.rossettings import RosSettings


@pytest.mark.parametrize("bridge", [RosBridge, Ros1Bridge])
@pytest.mark.parametrize(
    ("name", "resolved"),
    [
        ("~foo", "/husky1/btcap/foo"),
        ("~/foo", "/husky1/btcap/foo"),
        ("~foo/bar", "/husky1/btcap/foo/bar"),
        ("~", "/husky1/btcap"),
        ("foo", "/husky1/foo"),
        ("/foo", "/foo"),
    ],
)
def test_a_name_resolves_in_the_robots_namespace(
    bridge: type[RosBridge], name: str, resolved: str
) -> None:
    backend = "ros1" if bridge is Ros1Bridge else "ros2"
    assert bridge(RosSettings(backend=backend), robot="husky1").resolve(name) == resolved


def test_a_private_name_of_a_node_at_the_root() -> None:
    bridge = RosBridge(RosSettings(namespace="/"), robot="husky1")
    assert bridge.resolve("~foo") == "/btcap/foo"


@pytest.mark.parametrize(("bridge", "label"), [(RosBridge, "ROS 2"), (Ros1Bridge, "ROS 1")])
def test_a_bad_name_is_refused_in_the_terms_of_the_bridges_ros(
    bridge: type[RosBridge], label: str
) -> None:
    backend = "ros1" if bridge is Ros1Bridge else "ros2"
    with pytest.raises(ValueError, match=f"ROS name: '/husky1/9lives' is no {label} namespace"):
        bridge(RosSettings(backend=backend), robot="husky1").resolve("9lives")
