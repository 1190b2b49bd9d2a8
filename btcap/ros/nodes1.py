"""The ROS tree node types of a robot on ROS 1: the same nodes, typing their ports and
filling their messages from ROS 1's genpy classes (:data:`btcap.ros.versions.ROS1`).

An agent whose ``ros:`` block says ``backend: ros1`` registers these under the usual names
(``RosAction``...: :func:`btcap.ros.agent.register` given :data:`NODE_TYPES1`), so its
tree files are the ones a ROS 2 robot runs. A node given a
:class:`~btcap.ros.client1.Ros1Bridge` as ``bridge=`` takes ROS 1's types from it, so
Python code may use either set.
"""

from __future__ import annotations

from typing import ClassVar

from btcap.bt.node import Node
from btcap.ros import action, service, topic
from btcap.ros.versions import ROS1, Types

__all__ = [
    "NODE_TYPES1",
    "RosAction",
    "RosPublish",
    "RosService",
    "RosSubscribe",
    "RosWaitForMessage",
]


class RosAction(action.RosAction):
    __doc__ = action.RosAction.__doc__
    __slots__ = ()
    TYPES: ClassVar[Types] = ROS1


class RosService(service.RosService):
    __doc__ = service.RosService.__doc__
    __slots__ = ()
    TYPES: ClassVar[Types] = ROS1


class RosPublish(topic.RosPublish):
    __doc__ = topic.RosPublish.__doc__
    __slots__ = ()
    TYPES: ClassVar[Types] = ROS1


class RosSubscribe(topic.RosSubscribe):
    __doc__ = topic.RosSubscribe.__doc__
    __slots__ = ()
    TYPES: ClassVar[Types] = ROS1


class RosWaitForMessage(topic.RosWaitForMessage):
    __doc__ = topic.RosWaitForMessage.__doc__
    __slots__ = ()
    TYPES: ClassVar[Types] = ROS1


#: The ROS 1 node types, by the names tree files use.
NODE_TYPES1: tuple[type[Node], ...] = (
    RosAction,
    RosService,
    RosPublish,
    RosSubscribe,
    RosWaitForMessage,
)
