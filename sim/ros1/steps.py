"""A simulated robot's implementations behind ROS 1, made of the bridge's own tree nodes, as
the paper's robots have them: a RosAction on the robot's ``move_base``
(``move_base_msgs/MoveBase``), then a RosService on the simulation manager's ``explore``,
``identify`` or ``decontaminate`` service. :class:`~btcap.sim.ros2.steps.CellPose` turns a
map cell into the pose of ``move_base``'s ``target_pose``; :class:`OperateAnswer` fails the
step when the service answers ``ok: false``, saying why (a service call has no status of
its own). No rospy here: the nodes talk to the robot's rospy process through its bridge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from btcap import Leaf, Port, State
from btcap.ros.client import RosBridge
from btcap.ros.nodes1 import RosAction, RosService
from btcap.sim.mission.capabilities import Step
from btcap.sim.ros1.names1 import MOVE_BASE, MOVE_BASE_TYPE, OPERATE_TYPE
from btcap.sim.ros2.steps import SERVER_TIMEOUT_S, CellPose

__all__ = ["OperateAnswer", "RosDrive1"]


class OperateAnswer(Leaf):
    """SUCCEEDED with the operation's ``found`` and ``contaminated`` if it answered ``ok``;
    else FAILED (as the manager's own leaves do; ``detail`` is on the tree's blackboard)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {
        "ok": Port(bool, False),
        "detail": Port(str, ""),
        "found": Port(int, 0),
        "contaminated": Port(bool, False),
    }
    OUTPUTS: ClassVar[Any] = {"found": int, "contaminated": bool}

    def on_tick(self) -> State:
        if not self.inputs["ok"]:  # as the manager's own leaves: a failed step, no error
            return State.FAILED
        self.outputs["found"] = int(self.inputs["found"])
        self.outputs["contaminated"] = bool(self.inputs["contaminated"])
        return State.SUCCEEDED


@dataclass(frozen=True, slots=True)
class RosDrive1:
    """A :class:`~btcap.sim.mission.capabilities.Drive` of ROS 1 nodes on ``bridge`` (the robot's
    :class:`~btcap.ros.client1.Ros1Bridge`), names relative to its namespace.
    ``call_timeout_s``: wall seconds an operation's call may take (its work and, for
    decontaminate, the carry)."""

    bridge: RosBridge
    cell_size_m: float
    call_timeout_s: float

    def move(self, name: str) -> Step:
        pose = CellPose(f"{name}_pose", cell_size_m=self.cell_size_m)
        nav = RosAction(
            name,
            action_type=MOVE_BASE_TYPE,
            action_name=MOVE_BASE,
            server_timeout=SERVER_TIMEOUT_S,
            bridge=self.bridge,
        )
        return Step((pose, nav), ((pose, "pose", nav, "target_pose"),))

    def operate(self, name: str, op: str) -> Step:
        call = RosService(
            f"{name}_call",
            # explore works where the robot stands: no object (-1); the others are wired one
            inputs={"target": -1} if op == "explore" else None,
            service_type=OPERATE_TYPE,
            service_name=op,
            wait_for_server_timeout=SERVER_TIMEOUT_S,
            server_timeout=self.call_timeout_s,
            bridge=self.bridge,
        )
        answer = OperateAnswer(name)
        wires = tuple((call, k, answer, k) for k in ("ok", "detail", "found", "contaminated"))
        return Step((call, answer), wires)
