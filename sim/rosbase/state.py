"""A robot's state, as the simulator behind ROS 1 or ROS 2 publishes it, told to its
:class:`~btcap.sim.world.robot.Body`, and the robots' bridges closed: the part of the robots'
links the two backends' clients (:mod:`btcap.sim.ros1.client`, :mod:`btcap.sim.ros2.client`)
share.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Collection
from typing import Any

from btcap.actors import Actor
from btcap.sim.world.messages import PositionUpdate

__all__ = ["StateLink", "close_bridges"]


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


def close_bridges(bridges: Collection[Any]) -> None:
    """Close the robots' bridges (ROS 1 or ROS 2) all at once, each on a thread of its own:
    one by one, a team's close took the sum of theirs (each waits for its servers to answer
    its cancels, a ROS 1 one for its rospy process to exit). The first error, after all."""
    errors: list[BaseException] = []

    def close(bridge: Any) -> None:
        try:
            bridge.close()
        except BaseException as exc:  # raised below, once every bridge is closed
            errors.append(exc)

    threads = [threading.Thread(target=close, args=(b,), name="btcap close") for b in bridges]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
