"""The workload of the deterministic simulation test: capabilities whose runs report every
tick to a :class:`~btcap.sim.faults.check.Checker`, so it sees who executes what, when."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from btcap.bt.composites import Parallel, ReactiveSequence, Sequence
from btcap.bt.node import Leaf, Node
from btcap.bt.state import RUNNING, SUCCEEDED, State
from btcap.bt.tree import Tree
from btcap.sim.faults.check import Checker
from btcap.sim.faults.plan import CAPABILITIES, Plan, TaskSpec
from btcap.team.capabilities.capability import Capability, CapabilityInterface
from btcap.team.capabilities.implementation import Implementation

__all__ = ["INTERFACES", "implementations", "mission"]

INTERFACES = {
    name: CapabilityInterface(
        name,
        inputs={"task": str, "duration": float},
        outputs={"robot": str, "run": int},
        description=f"a {name.lower()} job of the simulation test, done after `duration` s",
    )
    for name in CAPABILITIES
}


class Job(Leaf):
    """Runs for its ``duration`` input in clock seconds, reporting each tick."""

    __slots__ = ("_checker", "_robot", "_run", "_started")
    INPUTS: ClassVar[Any] = {"task": str, "duration": float}
    OUTPUTS: ClassVar[Any] = {"robot": str, "run": int}

    def __init__(self, checker: Checker, robot: str) -> None:
        self._checker, self._robot = checker, robot
        self._run = checker.new_run()
        self._started: float | None = None
        super().__init__("job")

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._started is None:
            self._started = now
        self._checker.tick(self._robot, self._run, self.inputs["task"], now)
        self.outputs["robot"] = self._robot
        self.outputs["run"] = self._run
        if now - self._started >= self.inputs["duration"]:
            self._checker.end(self._run)
            return SUCCEEDED
        return RUNNING

    def on_shutdown(self) -> None:
        self._checker.end(self._run)


def _build(iface: CapabilityInterface, checker: Checker, robot: str) -> Tree:
    ib, ob = iface.bridge_types()
    i, job, o = ib(name="in"), Job(checker, robot), ob(name="out")
    tree = Tree(ReactiveSequence("impl", children=[i, job, o]))
    tree.wire(i, "task", job, "task")
    tree.wire(i, "duration", job, "duration")
    tree.wire(job, "robot", o, "robot")
    tree.wire(job, "run", o, "run")
    return tree


def implementations(plan: Plan, robot: str, checker: Checker) -> list[Implementation]:
    """What ``robot`` offers: its skills, each bidding cost x duration."""
    out = []
    for skill in plan.robots.get(robot, ()):
        iface = INTERFACES[skill.capability]

        def bid(inputs: Mapping[str, Any], cost: float = skill.cost) -> float:
            return cost * float(inputs["duration"])

        def build(iface: CapabilityInterface = iface) -> Tree:
            return _build(iface, checker, robot)

        out.append(Implementation(iface.name.lower(), iface, build, (), bid))
    return out


def mission(plan: Plan, tasks: tuple[TaskSpec, ...] | None = None) -> tuple[Node, list[Capability]]:
    """The mission tree of ``tasks`` (the plan's first mission by default) and its
    capability nodes, one per task."""
    nodes = [
        INTERFACES[t.capability].node_type()(
            t.name, inputs={"task": t.name, "duration": t.duration_s}
        )
        for t in (plan.tasks if tasks is None else tasks)
    ]
    root: Node = (
        Sequence("mission", children=list(nodes))
        if plan.sequence
        else Parallel("mission", children=list(nodes))
    )
    return root, nodes
