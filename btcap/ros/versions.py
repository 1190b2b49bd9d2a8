"""The interface functions of each ROS version, as one value a node or bridge holds.

A ROS tree node types its ports and fills its messages with the functions of its robot's
ROS version: :mod:`btcap.ros.interfaces` for ROS 2 (rosidl classes),
:mod:`btcap.ros.interfaces1` for ROS 1 (genpy classes). Both take the same type names and
plain values, so a tree file is the same for either. Importing this imports nothing of ROS.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

from btcap.ros import interfaces, interfaces1

__all__ = ["ROS1", "ROS2", "Types"]


class Types(NamedTuple):
    """One ROS version's interface functions (see :mod:`btcap.ros.interfaces`)."""

    version: int
    interface: Callable[[str, str], Any]
    field_types: Callable[[Any], dict[str, str]]
    fill: Callable[[Any, Mapping[str, Any], str], Any]
    port_type: Callable[[str], Any]
    to_plain: Callable[[Any], Any]


ROS2 = Types(
    2,
    interfaces.interface,
    interfaces.field_types,
    interfaces.fill,
    interfaces.port_type,
    interfaces.to_plain,
)
ROS1 = Types(
    1,
    interfaces1.interface1,
    interfaces1.field_types1,
    interfaces1.fill1,
    interfaces1.port_type1,
    interfaces1.to_plain1,
)
