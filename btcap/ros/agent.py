"""What an agent whose file has a ``ros:`` block runs beside it (``btcap agent``), found
by the agent through the ``btcap.ros`` entry point so that nothing of this package is
imported by an agent without the block.

It registers the ROS node types for the robot's tree files, starts the robot's
:class:`~btcap.ros.client.RosBridge` (in a worker thread: imports and discovery never
hold the event loop) before the implementation files are loaded, makes every
implementation whose tree calls ROS servers bid only while they answer, prices the
distance bids declared in implementation files (``bid: {distance_from: ...}``), gives the
bridge to the agent's actor system, and closes it when the agent stops.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

import anyio

from btcap.actors import ActorSystem
from btcap.bt.node import Node
from btcap.bt.registry import NodeRegistry
from btcap.ros.action import RosAction
from btcap.ros.capability import RosCost, distance_cost, servers_of, with_ros
from btcap.ros.client import RosBridge
from btcap.ros.errors import RosError
from btcap.ros.service import RosService
from btcap.ros.topic import RosPublish, RosSubscribe, RosWaitForMessage
from btcap.team.capabilities.capfiles import DistanceBid, FileBid
from btcap.team.capabilities.implementation import Implementation
from btcap.team.rossettings import RosSettings

__all__ = ["NODE_TYPES", "RosAgent", "register"]

#: The ROS node types, by the names tree files use.
NODE_TYPES: tuple[type[Node], ...] = (
    RosAction,
    RosService,
    RosPublish,
    RosSubscribe,
    RosWaitForMessage,
)


def register(registry: NodeRegistry, types: Iterable[type[Node]] = NODE_TYPES) -> NodeRegistry:
    """Add the ROS node types to ``registry`` (those whose names it lacks) and return it;
    ``types``: another set under the same names (ROS 1's ``nodes1.NODE_TYPES1``)."""
    for cls in types:
        if cls.__name__ not in registry:
            registry.register(cls)
    return registry


class RosAgent:
    """The ROS side of one agent: see the module docstring."""

    def __init__(self, settings: RosSettings, robot: str) -> None:
        if settings.backend == "ros1":
            from btcap.ros.client1 import Ros1Bridge

            self.bridge: RosBridge = Ros1Bridge(settings, robot=robot)
        else:
            self.bridge = RosBridge(settings, robot=robot)

    def register(self, registry: NodeRegistry) -> None:
        if self.bridge.types.version == 1:
            from btcap.ros.nodes1 import NODE_TYPES1

            register(registry, NODE_TYPES1)
        else:
            register(registry)

    async def start(self) -> None:
        await anyio.to_thread.run_sync(self.bridge.start)

    def wrap(self, implementations: Iterable[Implementation]) -> list[Implementation]:
        """Each implementation bidding only while its servers answer, and at the distance
        its file declares; RosError naming the file for a pose type that cannot work."""
        out = []
        for impl in implementations:
            servers = servers_of(impl.build())
            bid = impl.bid
            if isinstance(bid, FileBid) and bid.distance is not None:
                cost = self.distance(bid.distance)
                plain = dataclasses.replace(impl, bid=bid.without_distance())
                out.append(with_ros(plain, self.bridge, servers=servers, cost=cost))
            else:
                out.append(with_ros(impl, self.bridge, servers=servers) if servers else impl)
        return out

    def distance(self, d: DistanceBid) -> RosCost:
        """The cost of a declared distance bid, its pose topic subscribed from now (so
        that the first call for bids finds a pose)."""
        try:
            self.bridge.latest(d.type, d.topic)
        except RosError as exc:
            raise RosError(f"{d.where}: bid.distance_from: {exc}") from None
        return distance_cost(
            d.to, pose_topic=d.topic, pose_type=d.type, factor=d.factor, max_age_s=d.max_age_s
        )

    def attach(self, system: ActorSystem) -> None:
        self.bridge.provide(system)

    async def close(self) -> None:
        with anyio.CancelScope(shield=True):
            await anyio.to_thread.run_sync(self.bridge.close)
