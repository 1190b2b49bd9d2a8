"""Capability implementations that call ROS: bid only while their servers answer, and
optionally at a cost read from a topic (the robot's pose for a distance bid).

An implementation whose tree holds RosAction and RosService nodes needs their servers:
:func:`with_ros` wraps its bid so the robot declines (bids None) while any of them is
missing from the ROS graph, and adds ``cost(inputs, bridge)`` if given. The agent does
this for every implementation file when its file has a ``ros:`` block; programs call it
(or :func:`ros_implementation`) themselves. A robot that declines because the only server
of a name has another type says so once per server and type (a
:class:`~btcap.ros.errors.RosTypeWarning` and the log line ``btcap.ros.type_mismatch``,
naming the robot, the implementation, the name and both types): it would otherwise just
never take the task, and nobody would know why.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any, NamedTuple

from btcap.bt.node import Node
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.ros.service import RosService
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation, Precondition

__all__ = ["RosCost", "Server", "distance_cost", "ros_implementation", "servers_of", "with_ros"]

#: What a server of another type does to a bid (after "type mismatch: ...").
_DECLINED = "it declines to bid until a server of its type answers"

#: ``cost(inputs, bridge)``: a bid term, or None for "cannot do these inputs".
RosCost = Callable[[Mapping[str, Any], RosBridge], float | None]


class Server(NamedTuple):
    """A server an implementation needs: ``kind`` is ``action`` or ``service``."""

    kind: str
    type_name: str
    name: str


def servers_of(root: Node | Tree) -> list[Server]:
    """The action and service servers the RosAction/RosService nodes of a tree call, by
    the names they are given literally (a name read from the blackboard or a wire is
    known only when the node runs: pass such servers to :func:`with_ros` yourself)."""
    nodes = root.nodes() if isinstance(root, Tree) else root.walk()
    out: list[Server] = []
    for n in nodes:
        if not isinstance(n, RosAction | RosService):
            continue
        name = n.literal_name()
        if name is None:
            continue
        if isinstance(n, RosAction):
            s = Server("action", n.options["action_type"], name)
        else:
            s = Server("service", n.options["service_type"], name)
        if s not in out:
            out.append(s)
    return out


def with_ros(
    impl: Implementation,
    bridge: RosBridge,
    *,
    servers: Iterable[Server] | None = None,
    cost: RosCost | None = None,
) -> Implementation:
    """``impl``, bidding only while ``servers`` (by default: those its tree calls) are in
    the ROS graph, plus ``cost(inputs, bridge)``."""
    needed = list(servers) if servers is not None else servers_of(impl.build())
    inner = impl.bid
    # Who is told, once per server and type, when the only server there has another type.
    asker = (
        f"robot {bridge.robot or bridge.fqn}, implementation {impl.name!r} of capability "
        f"{impl.interface.name}"
    )

    def bid(inputs: Mapping[str, Any]) -> float | None:
        for s in needed:
            if not bridge.server_ready(s.kind, s.type_name, s.name, asker, _DECLINED):
                return None
        total = 0.0
        for term in (
            inner(inputs) if inner is not None else 0.0,
            cost(inputs, bridge) if cost is not None else 0.0,
        ):
            if term is None:
                return None
            total += float(term)
        return total

    return dataclasses.replace(impl, bid=bid)


def ros_implementation(
    name: str,
    interface: CapabilityInterface,
    build: Callable[[], Node | Tree],
    bridge: RosBridge,
    *,
    preconditions: tuple[Precondition, ...] = (),
    servers: Iterable[Server] | None = None,
    cost: RosCost | None = None,
) -> Implementation:
    """An implementation of ``interface`` made of ROS nodes (see :func:`with_ros`)."""
    impl = Implementation(name, interface, build, preconditions)
    return with_ros(impl, bridge, servers=servers, cost=cost)


def distance_cost(
    goal_input: str = "goal",
    *,
    pose_topic: str = "pose",
    pose_type: str = "geometry_msgs/msg/PoseStamped",
    factor: float = 1.0,
    max_age_s: float | None = None,
) -> RosCost:
    """A cost: ``factor`` x the straight-line distance from the robot's latest pose (a
    PoseStamped, or a Pose, on ``pose_topic`` in its namespace) to the ``goal_input``
    input (``[x, y]`` or a dict with ``x``/``y``, or a PoseStamped-shaped dict). No pose
    yet, or one older than ``max_age_s``: None (the robot does not bid)."""

    def cost(inputs: Mapping[str, Any], bridge: RosBridge) -> float | None:
        latest = bridge.latest(pose_type, pose_topic)
        if latest is None:
            return None
        message, at = latest
        if max_age_s is not None:
            import time

            if time.monotonic() - at > max_age_s:
                return None
        here = _xy(bridge.types.to_plain(message))
        there = _xy(inputs[goal_input])
        if here is None or there is None:
            return None
        return factor * math.dist(here, there)

    return cost


def _xy(value: Any) -> tuple[float, float] | None:
    if isinstance(value, list | tuple) and len(value) >= 2:
        return float(value[0]), float(value[1])
    if isinstance(value, Mapping):
        for key in ("pose", "position"):
            if key in value:
                return _xy(value[key])
        if "x" in value and "y" in value:
            return float(value["x"]), float(value["y"])
    return None
