"""``Work``: a capability that takes its time and writes down every tick it executes.

The plugin (``plugin: {factory: "tracedwork:implementations", ...}`` in an agent file)
of the robots in tests/btcap/team/deployment/test_partitions.py: each tick of a run
appends ``{"t": time.monotonic(), "robot", "task", "run"}`` to the robot's trace file, so
the test sees where and when each run really executed, not what the team believed.
``time.monotonic()`` is one clock for every process on the host, whatever its network
namespace.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, ClassVar

from btcap import (
    Implementation,
    Leaf,
    Port,
    ReactiveSequence,
    State,
    Tree,
    load_interfaces,
)

__all__ = ["INTERFACES", "TracedWork", "implementations", "read_trace"]

#: The interface file every member loads (the operator's mission tree names ``Work``).
INTERFACES = """\
btcap_interfaces: 1
interfaces:
  - name: Work
    description: Work on a task for some seconds, then say which robot did it.
    inputs: {task: str, seconds: float}
    outputs: {robot: str}
"""


class TracedWork(Leaf):
    """Runs until ``seconds`` of its clock have passed since its first tick; every tick
    is a line in the trace file."""

    __slots__ = ("_started",)
    INPUTS: ClassVar[Any] = {"task": Port(str | None, None), "seconds": Port(float | None, None)}
    OUTPUTS: ClassVar[Any] = {"robot": str}
    OPTIONS: ClassVar[Any] = {"robot": Port(str, ""), "trace": Port(str, "")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._started: float | None = None
        super().__init__(*args, **kwargs)

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._started is None:
            self._started = now
        line = {
            "t": time.monotonic(),
            "robot": self.options["robot"],
            "task": self.inputs["task"],
            "run": self.tree.name,  # the execution id: a fresh tree per award
        }
        with open(self.options["trace"], "a") as trace:
            trace.write(json.dumps(line) + "\n")
        self.outputs["robot"] = self.options["robot"]
        if now - self._started >= (self.inputs["seconds"] or 0.0):
            return State.SUCCEEDED
        return State.RUNNING

    def on_reset(self) -> None:
        self._started = None

    def on_shutdown(self) -> None:
        """A run that ticked is stopped: its last line (it acted until now)."""
        if self._started is not None:
            line = {"t": time.monotonic(), "run": self.tree.name, "stop": True}
            with open(self.options["trace"], "a") as trace:
                trace.write(json.dumps(line) + "\n")


def implementations(
    robot: str, interfaces: str, trace: str, cost: float = 1.0
) -> list[Implementation]:
    """``robot``'s implementation of ``Work`` (declared in the file ``interfaces``),
    bidding ``cost`` and tracing to the file ``trace``."""
    (work,) = load_interfaces(interfaces)

    def build() -> Tree:
        inputs, outputs = work.bridge_types()
        bridge_in, bridge_out = inputs(name="inputs"), outputs(name="outputs")
        leaf = TracedWork("work", robot=robot, trace=trace)
        tree = Tree(ReactiveSequence("work_impl", children=[bridge_in, leaf, bridge_out]))
        tree.wire(bridge_in, "task", leaf, "task")
        tree.wire(bridge_in, "seconds", leaf, "seconds")
        tree.wire(leaf, "robot", bridge_out, "robot")
        return tree

    return [Implementation(f"work-{robot}", work, build, bid=lambda _inputs: cost)]


def read_trace(path: Path) -> list[dict[str, Any]]:
    """The ticks a trace file holds (none if the robot never ran anything)."""
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line]
