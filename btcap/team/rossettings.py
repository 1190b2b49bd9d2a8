"""The ``ros:`` block of agent and scenario files: which ROS graph (ROS 2, or ROS 1 with
``backend: ros1``) a robot joins.

Plain msgspec types, importing nothing of ROS, so the one settings schema (and ``btcap
schema agent``) covers the block while an agent without it never loads the bridge
(:mod:`btcap.ros`, which reads these settings when the block is there). Names follow
ROS 2's rules, checked here so a bad one is refused as the file is read, naming the field
and the ROS the block is for.
"""

from __future__ import annotations

import re
import urllib.parse
from typing import Annotated, Literal

import msgspec

__all__ = [
    "DomainId",
    "Qos",
    "RosBackend",
    "RosSettings",
    "check_master_uri",
    "check_namespace",
    "check_node_name",
    "ros_label",
]

_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_NAMESPACE = re.compile(rf"^(/{_TOKEN})+$|^/$")
_NODE = re.compile(rf"^{_TOKEN}$")


def _doc(text: str) -> msgspec.Meta:
    return msgspec.Meta(description=text)


#: The ROS a ``ros`` block is for: an agent's (:class:`RosSettings`) and the simulator's
#: (btcap.sim.mission.scenariofile's ``ScenarioRos``).
RosBackend = Literal["ros2", "ros1"]
#: The ROS 2 domain field of both ``ros`` blocks, with its bounds and its doc.
DomainId = Annotated[
    Annotated[int, msgspec.Meta(ge=0, le=232)] | None,
    _doc("The ROS 2 domain (0-232; 0-101 on every DDS); null: `ROS_DOMAIN_ID` or 0."),
]


def ros_label(backend: str) -> str:
    """``ROS 1`` or ``ROS 2``: the ROS a ``backend`` value names, for errors (a ROS 1
    block's errors must not send its user to ROS 2's rules)."""
    return "ROS 1" if backend == "ros1" else "ROS 2"


def check_namespace(value: str, where: str = "namespace", backend: str = "ros2") -> str:
    """``value`` if it is an absolute namespace (``/husky1``) of ``backend``'s ROS, else
    ValueError naming that ROS."""
    if not _NAMESPACE.match(value):
        raise ValueError(
            f"{where}: {value!r} is no {ros_label(backend)} namespace: expected '/' and names "
            "of letters, digits and '_' not starting with a digit ('/husky1', '/team/husky1')"
        )
    return value


def check_master_uri(value: str | None, where: str = "master_uri") -> str | None:
    """``value`` if it is a ROS 1 master's URI (``http://HOST:PORT/``) or None, else
    ValueError: rospy would take ``localhost:11311`` and fail only when the robot starts."""
    if value is None:
        return value
    try:
        url = urllib.parse.urlsplit(value)
        port = url.port
    except ValueError:
        port = None
        url = urllib.parse.urlsplit("")
    if url.scheme not in ("http", "https") or not url.hostname or port is None:
        raise ValueError(
            f"{where}: {value!r} is no ROS 1 master URI: expected http://HOST:PORT/ "
            "(e.g. http://localhost:11311/)"
        )
    return value


def check_node_name(value: str, where: str = "node_name", backend: str = "ros2") -> str:
    """``value`` if it is a node name (``btcap``) of ``backend``'s ROS, else ValueError
    naming that ROS."""
    if not _NODE.match(value):
        raise ValueError(
            f"{where}: {value!r} is no {ros_label(backend)} node name: expected letters, "
            "digits and '_', not starting with a digit"
        )
    return value


class Qos(msgspec.Struct, forbid_unknown_fields=True, kw_only=True, frozen=True):
    """A quality-of-service profile: the defaults of a robot, or one node's own."""

    reliability: Annotated[
        Literal["reliable", "best_effort"],
        _doc("`reliable` (resent until received) or `best_effort` (sensor data)."),
    ] = "reliable"
    durability: Annotated[
        Literal["volatile", "transient_local"],
        _doc("`volatile`, or `transient_local` (late joiners get the last `depth` messages)."),
    ] = "volatile"
    depth: Annotated[
        int, msgspec.Meta(ge=1, le=10000, description="History depth (keep last).")
    ] = 10


class RosSettings(msgspec.Struct, forbid_unknown_fields=True, kw_only=True, frozen=True):
    """The robot's ROS node: where in the ROS graph its tree nodes live."""

    backend: Annotated[
        RosBackend,
        _doc(
            "`ros2` (rclpy, docs/ros2.md) or `ros1` (rospy and actionlib in a process of "
            "the robot's own, on the master of `master_uri`: docs/ros1.md)."
        ),
    ] = "ros2"
    master_uri: Annotated[
        str | None,
        _doc("ROS 1 only: the master's URI; null: `ROS_MASTER_URI`, else http://localhost:11311/."),
    ] = None

    domain_id: DomainId = None
    namespace: Annotated[
        str | None,
        _doc(
            "The robot's namespace: every action, service and topic name of its tree nodes "
            "that does not start with '/' is resolved in it (`navigate_to_pose` -> "
            "`/husky1/navigate_to_pose`); null: '/' and the robot's name."
        ),
    ] = None
    node_name: Annotated[str, _doc("The name of the robot's ROS node.")] = "btcap"
    qos: Annotated[Qos, _doc("QoS of topics whose node sets none.")] = msgspec.field(
        default_factory=Qos
    )

    def __post_init__(self) -> None:
        if self.namespace is not None:
            check_namespace(self.namespace, backend=self.backend)
        check_node_name(self.node_name, backend=self.backend)
        check_master_uri(self.master_uri)

    def namespace_of(self, robot: str) -> str:
        """The namespace, ``/ROBOT`` when none is set (ValueError if that is no name)."""
        if self.namespace is not None:
            return self.namespace
        where = f"namespace (from the robot's name {robot!r})"
        return check_namespace(f"/{robot}", where, self.backend)
