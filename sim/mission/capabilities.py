"""The mission's capabilities and each robot's implementations of them.

Implementations are small trees of sim leaves: drive to the target, then ask the
simulation manager for the operation. A robot bids the paper's cost: path length to the
target (and, to decontaminate, on to the decontamination area) times its distance cost
factor, plus the operation's duration; or, bidding time (:data:`BidUnit`), the seconds
that drive takes at its speed, plus the operation's duration. The same estimate, asked
again while the robot drives or works, says what finishing would cost from where it is
now: the drive left and the work left (its :class:`~btcap.sim.world.robot.Body` hears of
every cell and operation).
A bid for other work *after* the work held (to queue it, or a time-extended bid; see
:func:`~btcap.team.core.bidding.bidding_after`) starts where that work leaves the robot:
the end of the run it drives for, or the decontamination area while it carries.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, Protocol

from btcap import Leaf, Node, Port, Sequence, State, Tree
from btcap.actors import Actor
from btcap.sim.mission.leaves import MoveToLeaf, OperateLeaf
from btcap.sim.world.distance import Cell, DistanceCache, path_length
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel
from btcap.sim.world.robot import Body
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.bidding import bidding_after

__all__ = [
    "DECONTAMINATE",
    "EXPLORE",
    "IDENTIFY",
    "INTERFACES",
    "ROBOT_CACHE_SIZE",
    "SPARE_EXPLORE",
    "STANDBY",
    "BidUnit",
    "Drive",
    "RobotSetup",
    "Step",
    "robot_setup",
]

#: What a bid is in: ``paper``, the paper's cost units (metres x cost factor + seconds of
#: work), or ``time``, seconds (the drive at the robot's speed + the work): the paper's
#: unit prices a Bebop's 21 m flight as 21 though it takes 7 s, so only time bids give
#: work to the robot that ends it first.
BidUnit = Literal["paper", "time"]

#: Distance fields each robot keeps for its bids (4 bytes a map cell each).
ROBOT_CACHE_SIZE = 64

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
STANDBY = CapabilityInterface(
    "StandBy",
    inputs={"at": tuple[int, int]},
    outputs={},
    description="Drive to where work may come soon (an object found, not yet identified), "
    "to be near when it does; only robots that can carry stand by.",
)
SPARE_EXPLORE = CapabilityInterface(
    "ExploreMeanwhile",
    inputs={"goal": tuple[int, int]},
    outputs={"found": Port(int, 0)},
    description="Explore a goal while no object work waits; only robots that can also "
    "identify or carry offer it, so cutting it short for such work frees a robot that "
    "can do that work (an explorer that can do nothing else is never stopped for it).",
)
#: The paper's capabilities (StandBy and ExploreMeanwhile are the pool mission's own,
#: offered beside them).
INTERFACES = (EXPLORE, IDENTIFY, DECONTAMINATE)


@dataclass(slots=True)
class RobotSetup:
    """What a simulated robot brings to its agent: implementations and extra actors."""

    implementations: list[Implementation]
    actors: dict[str, Actor]


@dataclass(frozen=True, slots=True)
class _Operation:
    """How one capability is implemented: drive to ``goal``, then ask the manager for ``op``
    (on the object in input ``target``, if any), bridging output ``result`` back."""

    interface: CapabilityInterface
    op: str  # the manager's operation, and the robot model's field
    leaf: str  # the name of the operate leaf in the implementation tree
    goal: str
    target: str | None = None
    result: str | None = None
    then_decon: bool = False  # the robot goes on to the decontamination area
    drive_only: bool = False  # no operation: the drive is the work (a robot able to ``op``)
    name: str = ""  # the implementation's name (before "-robot"); default: leaf or op
    also: tuple[str, ...] = ()  # offered only by robots able to do one of these too


_OPERATIONS = (
    _Operation(EXPLORE, "explore", "explore", goal="goal", result="found"),
    _Operation(IDENTIFY, "identify", "identify", goal="at", target="object", result="contaminated"),
    _Operation(
        DECONTAMINATE, "decontaminate", "carry", goal="at", target="object", then_decon=True
    ),
    _Operation(STANDBY, "decontaminate", "standby", goal="at", drive_only=True),
    _Operation(
        SPARE_EXPLORE,
        "explore",
        "explore",
        goal="goal",
        result="found",
        name="explore_meanwhile",
        also=("identify", "decontaminate"),
    ),
)


def _target(inputs: Mapping[str, Any], key: str) -> Cell | None:
    value = inputs.get(key)
    if value is None:
        return None
    return (int(value[0]), int(value[1]))


class _Heading(Leaf):
    """Tells the robot's body which run it now drives for and where that run leaves it
    (its goal; for a carry, the decontamination area), so bids for later made meanwhile
    start there; forgotten when the run stops (halted, reset or shut down)."""

    __slots__ = ("_body", "_end", "_op", "_told")
    INPUTS: ClassVar[Any] = {
        "goal": Port(tuple[int, int] | None, None),
        "target": Port(int | None, None),
    }

    def setup_heading(self, body: Body, op: str, end: Cell | None) -> None:
        self._body, self._op, self._end = body, op, end
        self._told: tuple[tuple[str, int, Cell], Cell] | None = None

    def on_tick(self) -> State:
        goal, target = self.inputs["goal"], self.inputs["target"]
        if goal is not None:
            cell = (int(goal[0]), int(goal[1]))
            key = (self._op, -1 if target is None else int(target), cell)
            self._told = self._body.heading = (key, self._end or cell)
        return State.SUCCEEDED

    def _forget(self) -> None:
        told = getattr(self, "_told", None)
        if told is not None and self._body.heading is told:
            self._body.heading = None
        self._told = None

    def on_untick(self) -> None:
        self._forget()

    def on_reset(self) -> None:
        self._forget()

    def on_shutdown(self) -> None:
        self._forget()


@dataclass(frozen=True, slots=True)
class Step:
    """Nodes that do one part of an implementation, in this order: the first takes its
    input (``goal`` to drive, ``target`` to operate), the last gives its outputs
    (``found``, ``contaminated``); ``wires`` (source, port, target, port) join them."""

    nodes: tuple[Node, ...]
    wires: tuple[tuple[Node, str, Node, str], ...] = ()


class Drive(Protocol):
    """Makes the nodes through which an implementation reaches the robot's body: by
    default leaves that ask the simulation manager; :mod:`btcap.sim.ros2` reaches it
    through the robot's ROS 2 actions (RosAction nodes) instead."""

    def move(self, name: str) -> Leaf | Step:
        """What drives to input ``goal``."""
        ...

    def operate(self, name: str, op: str) -> Leaf | Step:
        """What runs ``op`` on input ``target`` (outputs ``found``, ``contaminated``)."""
        ...


def _step(made: Leaf | Step) -> Step:
    return made if isinstance(made, Step) else Step((made,))


@dataclass(frozen=True, slots=True)
class _ManagerDrive:
    """The leaves that ask the simulation manager directly."""

    robot: str
    manager: str

    def move(self, name: str) -> Leaf:
        return MoveToLeaf(name, robot=self.robot, manager=self.manager)

    def operate(self, name: str, op: str) -> Leaf:
        return OperateLeaf(name, robot=self.robot, manager=self.manager, op=op)


def robot_setup(
    robot: str,
    model: RobotModel,
    grid: GridMap,
    *,
    manager: str = "sim/manager",
    drive: Drive | None = None,
    bids: BidUnit = "paper",
) -> RobotSetup:
    """The implementations of one simulated robot (only those its model can do), whose
    leaves ``drive`` makes (default: asking ``manager``), bidding in ``bids``: the
    paper's cost units, or seconds (:data:`BidUnit`)."""
    drive = drive or _ManagerDrive(robot, manager)
    body = Body(robot, grid.start)
    cache = DistanceCache(grid.free, maxsize=ROBOT_CACHE_SIZE)
    if bids not in ("paper", "time"):
        raise ValueError(f"bids: expected 'paper' or 'time', got {bids!r}")
    # a metre's price: the paper's cost factor, or the seconds it takes to drive
    cf = model.cost_factor if bids == "paper" else 1.0 / model.speed_mps

    def travel(a: Cell, b: Cell) -> float:
        return path_length(cache.get(b), a, grid.cell_size_m) * cf

    def implementation(o: _Operation) -> Implementation:
        duration = 0.0 if o.drive_only else model.operation(o.op).duration_s

        def bid(inputs: Mapping[str, Any]) -> float | None:
            """What finishing would cost from here and now: the drive left (from where the
            body is), then the work left (its duration less what is done)."""
            at = _target(inputs, o.goal)
            if at is None or not grid.is_free(at):
                return None
            target = None if o.target is None else inputs.get(o.target)
            if o.drive_only:  # the drive left is all of it
                left = None
            elif o.target is None:  # explore: where the robot stands
                left = body.left_s(o.op, -1, duration) if body.position == at else None
            else:
                left = None if target is None else body.left_s(o.op, int(target), duration)
            if left is None:  # not under way: drive there, work, (carry the object on)
                task = (o.leaf if o.drive_only else o.op, -1 if target is None else int(target), at)
                after = not model.bids_from_here and bidding_after()
                start = body.bound_for(grid.decon_area, task) if after else body.position
                cost = travel(start, at) + duration
                if o.then_decon:
                    cost += travel(at, grid.decon_area)
            elif o.then_decon and body.phase == "carry":
                cost = travel(body.position, grid.decon_area) + left
            else:
                cost = left
            return cost if math.isfinite(cost) else None

        def build() -> Tree:
            i, out = o.interface.bridge_types()
            bi = i(name="inputs")
            heading = _Heading("heading")
            heading.setup_heading(
                body, o.leaf if o.drive_only else o.op, grid.decon_area if o.then_decon else None
            )
            move = _step(drive.move("drive"))
            work = Step(()) if o.drive_only else _step(drive.operate(o.leaf, o.op))
            leaf = work.nodes[-1] if work.nodes else move.nodes[-1]
            bo = out(name="outputs") if o.result is not None else None
            children = [bi, heading, *move.nodes, *work.nodes]
            tree = Tree(Sequence(o.op, children=children if bo is None else [*children, bo]))
            for wire in (*move.wires, *work.wires):
                tree.wire(*wire)
            tree.wire(bi, o.goal, move.nodes[0], "goal")
            tree.wire(bi, o.goal, heading, "goal")
            if o.target is not None and work.nodes:
                tree.wire(bi, o.target, work.nodes[0], "target")
                tree.wire(bi, o.target, heading, "target")
            if bo is not None and o.result is not None:
                tree.wire(leaf, o.result, bo, o.result)
            return tree

        name = o.name or (o.leaf if o.drive_only else o.op)
        return Implementation(f"{name}-{robot}", o.interface, build, bid=bid)

    impls = [
        implementation(o)
        for o in _OPERATIONS
        if model.can(o.op) and (not o.also or any(model.can(k) for k in o.also))
    ]
    return RobotSetup(impls, {Body.PATH: body})
