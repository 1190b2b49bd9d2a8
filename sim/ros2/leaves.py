"""The sim leaves, reaching the robot through ROS 2: the same ticks, states, ports and
cancellation as :mod:`btcap.sim.leaves`, but each request is a goal of the robot's action
(a :class:`~btcap.sim.ros2.client.RobotLink`) instead of an ask of the simulation manager.
No rclpy import here: the link brings it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from btcap import Leaf
from btcap.sim.leaves import MoveToLeaf, OperateLeaf
from btcap.sim.messages import SimResult

if TYPE_CHECKING:
    from btcap.sim.ros2.client import RobotLink

__all__ = ["RosDrive", "RosMoveToLeaf", "RosOperateLeaf"]


class RosMoveToLeaf(MoveToLeaf):
    """Drives the robot to ``goal`` through its navigation action."""

    __slots__ = ("_link",)

    def setup_link(self, link: RobotLink) -> None:
        self._link = link

    async def _move(self, goal: tuple[int, int]) -> SimResult:
        return await self._link.navigate(goal)


class RosOperateLeaf(OperateLeaf):
    """Runs ``op`` on ``target`` through the robot's action of that name."""

    __slots__ = ("_link",)

    def setup_link(self, link: RobotLink) -> None:
        self._link = link

    async def _operate(self) -> SimResult:
        target = self.inputs["target"]
        return await self._link.operate(self.options["op"], -1 if target is None else target)


@dataclass(frozen=True, slots=True)
class RosDrive:
    """A :class:`~btcap.sim.capabilities.Drive` whose leaves reach the robot over ROS 2."""

    link: RobotLink

    def move(self, name: str) -> Leaf:
        leaf = RosMoveToLeaf(name, robot=self.link.robot)
        leaf.setup_link(self.link)
        return leaf

    def operate(self, name: str, op: str) -> Leaf:
        leaf = RosOperateLeaf(name, robot=self.link.robot, op=op)
        leaf.setup_link(self.link)
        return leaf
