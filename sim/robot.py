"""A simulated robot's own view of itself: where it is, as the simulation last said."""

from __future__ import annotations

from btcap.actors import Actor, handler
from btcap.sim.distance import Cell
from btcap.sim.messages import PositionUpdate

__all__ = ["Body"]


class Body(Actor):
    """Tracks the robot's cell, for bids; updated by every move result and stop."""

    PATH = "body"

    def __init__(self, robot: str, position: Cell) -> None:
        super().__init__()
        self.robot = robot
        self.position: Cell = position

    @handler
    def on_position(self, msg: PositionUpdate) -> None:
        if msg.robot == self.robot:
            self.position = (int(msg.position[0]), int(msg.position[1]))
