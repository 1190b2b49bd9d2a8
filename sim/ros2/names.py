"""What a simulated robot looks like on ROS 2: interface types, names in its namespace, and
how map cells become poses. Plain data, no rclpy: a real robot that joins the team offers
the same names (or a mapping of them) with its own servers."""

from __future__ import annotations

from dataclasses import dataclass

from btcap.sim.world.distance import Cell

__all__ = [
    "FRAME",
    "NAVIGATE_TYPE",
    "OPERATE_TYPE",
    "OPERATIONS",
    "STATE_TYPE",
    "RobotNames",
    "cell_of",
    "xy_of",
]

#: Interface types, by their ROS names. The navigation goal, result and feedback fields the
#: client uses are named as in ``nav2_msgs/action/NavigateToPose``, so a Nav2 robot is
#: driven by the same client given that type name.
NAVIGATE_TYPE = "btcap_sim_msgs/action/NavigateToPose"
OPERATE_TYPE = "btcap_sim_msgs/action/Operate"
STATE_TYPE = "btcap_sim_msgs/msg/RobotState"
#: The manager's operations, each an action of type OPERATE_TYPE named after it.
OPERATIONS = ("explore", "identify", "decontaminate")
#: The frame poses are given in: x along columns, y along rows, metres from cell (0, 0).
FRAME = "map"


@dataclass(frozen=True, slots=True)
class RobotNames:
    """The ROS names of one robot's interfaces, under its namespace (``ns``; None:
    ``/<robot>``, the default of a scenario's ``ros.namespace``)."""

    robot: str
    ns: str | None = None

    @property
    def namespace(self) -> str:
        return self.ns if self.ns is not None else f"/{self.robot}"

    @property
    def navigate(self) -> str:
        return f"{self.namespace}/navigate_to_pose"

    def operate(self, op: str) -> str:
        if op not in OPERATIONS:
            raise ValueError(f"operation {op!r}; expected one of {', '.join(OPERATIONS)}")
        return f"{self.namespace}/{op}"

    @property
    def pose(self) -> str:
        return f"{self.namespace}/pose"

    @property
    def state(self) -> str:
        return f"{self.namespace}/state"

    @property
    def stop(self) -> str:
        return f"{self.namespace}/stop"


def xy_of(cell: Cell, cell_size_m: float) -> tuple[float, float]:
    """A cell's centre as (x, y) metres in :data:`FRAME`."""
    return (cell[1] * cell_size_m, cell[0] * cell_size_m)


def cell_of(x: float, y: float, cell_size_m: float) -> Cell:
    """The cell whose centre is nearest to (x, y) metres in :data:`FRAME`."""
    return (round(y / cell_size_m), round(x / cell_size_m))
