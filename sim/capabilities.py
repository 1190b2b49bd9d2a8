"""The mission's capabilities and each robot's implementations of them.

Implementations are small trees of sim leaves: drive to the target, then ask the
simulation manager for the operation. A robot bids the paper's cost: path length to the
target (and, to decontaminate, on to the decontamination area) times its distance cost
factor, plus the operation's duration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from btcap import Port, SequenceWithMemory, Tree
from btcap.actors import Actor
from btcap.sim.distance import Cell, DistanceCache, path_length
from btcap.sim.grid import GridMap
from btcap.sim.leaves import MoveToLeaf, OperateLeaf
from btcap.sim.model import RobotModel
from btcap.sim.robot import Body
from btcap.team.capability import CapabilityInterface, Implementation

__all__ = [
    "DECONTAMINATE",
    "EXPLORE",
    "IDENTIFY",
    "INTERFACES",
    "RobotSetup",
    "robot_setup",
]

EXPLORE = CapabilityInterface(
    "Explore",
    inputs={"goal": tuple[int, int]},
    outputs={"found": Port(int, 0)},
    description="Drive to a goal and reveal objects and new goals within the robot's radius.",
)
IDENTIFY = CapabilityInterface(
    "IdentifyObject",
    inputs={"object": int, "at": tuple[int, int]},
    outputs={"contaminated": Port(bool, False)},
    description="Drive to an object and find out whether it is contaminated.",
)
DECONTAMINATE = CapabilityInterface(
    "MoveToDecontamination",
    inputs={"object": int, "at": tuple[int, int]},
    outputs={},
    description="Carry a contaminated object to the decontamination area.",
)
INTERFACES = (EXPLORE, IDENTIFY, DECONTAMINATE)


@dataclass(slots=True)
class RobotSetup:
    """What a simulated robot brings to its agent: implementations and extra actors."""

    implementations: list[Implementation]
    actors: dict[str, Actor]


def _target(inputs: Mapping[str, Any], key: str) -> Cell | None:
    value = inputs.get(key)
    if value is None:
        return None
    return (int(value[0]), int(value[1]))


def robot_setup(
    robot: str, model: RobotModel, grid: GridMap, *, manager: str = "sim/manager"
) -> RobotSetup:
    """The implementations of one simulated robot (only those its model can do)."""
    body = Body(robot, grid.start)
    cache = DistanceCache(grid.free, maxsize=64)
    cf = model.cost_factor

    def travel(a: Cell, b: Cell) -> float:
        return path_length(cache.get(b), a, grid.cell_size_m) * cf

    impls: list[Implementation] = []

    if model.explore is not None:
        duration = model.explore.duration_s

        def bid_explore(inputs: Mapping[str, Any]) -> float | None:
            goal = _target(inputs, "goal")
            if goal is None or not grid.is_free(goal):
                return None
            cost = travel(body.position, goal) + duration
            return cost if math.isfinite(cost) else None

        def build_explore() -> Tree:
            i, o = EXPLORE.bridge_types()
            bi, bo = i(name="inputs"), o(name="outputs")
            move = MoveToLeaf("drive", robot=robot, manager=manager)
            op = OperateLeaf("explore", robot=robot, manager=manager, op="explore")
            tree = Tree(SequenceWithMemory("explore", children=[bi, move, op, bo]))
            tree.wire(bi, "goal", move, "goal")
            tree.wire(op, "found", bo, "found")
            return tree

        impls.append(Implementation(f"explore-{robot}", EXPLORE, build_explore, bid=bid_explore))

    if model.identify is not None:
        duration_i = model.identify.duration_s

        def bid_identify(inputs: Mapping[str, Any]) -> float | None:
            at = _target(inputs, "at")
            if at is None:
                return None
            cost = travel(body.position, at) + duration_i
            return cost if math.isfinite(cost) else None

        def build_identify() -> Tree:
            i, o = IDENTIFY.bridge_types()
            bi, bo = i(name="inputs"), o(name="outputs")
            move = MoveToLeaf("drive", robot=robot, manager=manager)
            op = OperateLeaf("identify", robot=robot, manager=manager, op="identify")
            tree = Tree(SequenceWithMemory("identify", children=[bi, move, op, bo]))
            tree.wire(bi, "at", move, "goal")
            tree.wire(bi, "object", op, "target")
            tree.wire(op, "contaminated", bo, "contaminated")
            return tree

        impls.append(
            Implementation(f"identify-{robot}", IDENTIFY, build_identify, bid=bid_identify)
        )

    if model.decontaminate is not None:
        duration_d = model.decontaminate.duration_s

        def bid_decon(inputs: Mapping[str, Any]) -> float | None:
            at = _target(inputs, "at")
            if at is None:
                return None
            cost = travel(body.position, at) + travel(at, grid.decon_area) + duration_d
            return cost if math.isfinite(cost) else None

        def build_decon() -> Tree:
            i, _o = DECONTAMINATE.bridge_types()
            bi = i(name="inputs")
            move = MoveToLeaf("drive", robot=robot, manager=manager)
            op = OperateLeaf("carry", robot=robot, manager=manager, op="decontaminate")
            tree = Tree(SequenceWithMemory("decontaminate", children=[bi, move, op]))
            tree.wire(bi, "at", move, "goal")
            tree.wire(bi, "object", op, "target")
            return tree

        impls.append(
            Implementation(f"decontaminate-{robot}", DECONTAMINATE, build_decon, bid=bid_decon)
        )

    return RobotSetup(impls, {Body.PATH: body})
