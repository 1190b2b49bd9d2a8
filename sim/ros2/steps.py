"""A simulated robot's implementations behind ROS 2, made of the bridge's own tree nodes:
a :class:`~btcap.ros.action.RosAction` on the robot's ``navigate_to_pose`` action, then one
on its ``explore``, ``identify`` or ``decontaminate`` action, as a real robot's
implementation files have them (docs/ros2-sim.md). The only sim-specific node is
:class:`CellPose`, which turns the mission's map cells into the poses a navigation goal
takes. No rclpy import here: RosAction loads it when built, and the host has loaded it by
then.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from btcap import Leaf, Port, State
from btcap.ros.action import RosAction
from btcap.ros.client import RosBridge
from btcap.sim.mission.capabilities import Step
from btcap.sim.ros2.names import FRAME, NAVIGATE_TYPE, OPERATE_TYPE, xy_of

__all__ = ["SERVER_TIMEOUT_S", "CellPose", "RosDrive"]

#: Wall seconds a RosAction waits for its server and for the goal's acceptance: the robots'
#: servers are found before the mission starts; this only bounds a server gone quiet.
SERVER_TIMEOUT_S = 10.0


class CellPose(Leaf):
    """The map cell of input ``goal`` as a ``geometry_msgs/PoseStamped`` (plain fields,
    :data:`~btcap.sim.ros2.names.FRAME`), for a navigation goal's ``pose``."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"goal": Port(tuple[int, int] | None, None)}
    OUTPUTS: ClassVar[Any] = {"pose": dict[str, Any]}
    OPTIONS: ClassVar[Any] = {"cell_size_m": Port(float, 1.0, "the side of a map cell")}

    def on_tick(self) -> State:
        goal = self.inputs["goal"]
        if goal is None:
            return State.FAILED
        x, y = xy_of((int(goal[0]), int(goal[1])), self.options["cell_size_m"])
        self.outputs["pose"] = {
            "header": {"frame_id": FRAME},
            "pose": {"position": {"x": x, "y": y}, "orientation": {"w": 1.0}},
        }
        return State.SUCCEEDED


@dataclass(frozen=True, slots=True)
class RosDrive:
    """A :class:`~btcap.sim.mission.capabilities.Drive` of RosAction nodes on ``bridge`` (the
    robot's), names relative to its namespace."""

    bridge: RosBridge
    cell_size_m: float

    def move(self, name: str) -> Step:
        pose = CellPose(f"{name}_pose", cell_size_m=self.cell_size_m)
        nav = RosAction(
            name,
            action_type=NAVIGATE_TYPE,
            action_name="navigate_to_pose",
            server_timeout=SERVER_TIMEOUT_S,
            bridge=self.bridge,
        )
        return Step((pose, nav), ((pose, "pose", nav, "pose"),))

    def operate(self, name: str, op: str) -> RosAction:
        return RosAction(
            name,
            # explore works where the robot stands: no object (-1); the others are wired one
            inputs={"target": -1} if op == "explore" else None,
            action_type=OPERATE_TYPE,
            action_name=op,
            server_timeout=SERVER_TIMEOUT_S,
            bridge=self.bridge,
        )
