"""A robot's state, as the simulator behind ROS 1 or ROS 2 publishes it, told to its
:class:`~btcap.sim.world.robot.Body`: the part of a robot's link the two backends' clients
(:mod:`btcap.sim.ros1.client`, :mod:`btcap.sim.ros2.client`) share.
"""

from __future__ import annotations

import asyncio
from typing import Any

from btcap.actors import Actor
from btcap.sim.world.messages import PositionUpdate

__all__ = ["StateLink"]


class StateLink:
    """Robot ``robot``'s state messages told, on ``loop``, to ``body`` once spawned."""

    def __init__(self, robot: str, loop: asyncio.AbstractEventLoop) -> None:
        self.robot, self.loop = robot, loop
        self.body: Actor | None = None

    def _on_state(self, msg: Any) -> None:  # the bridge's thread
        update = PositionUpdate(
            self.robot, (int(msg.row), int(msg.col)), msg.operation, int(msg.target), msg.phase
        )
        self.loop.call_soon_threadsafe(self._tell_body, update)

    def _tell_body(self, update: PositionUpdate) -> None:
        body = self.body
        if body is not None and body._system is not None:
            body.ref.tell(update)
