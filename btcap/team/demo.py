"""A small demo capability, ``Echo``, for examples, tests and benchmarks across processes.

``Echo`` copies its ``value`` input to its ``value`` output on every tick and counts the
ticks, running until its ``stop`` input is true (or ``duration_s`` clock seconds passed,
if given). Robots bid a fixed ``cost`` given to :func:`implementations`.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.composites import ReactiveSequence
from btcap.bt.node import Leaf
from btcap.bt.ports import Port
from btcap.bt.state import RUNNING, SUCCEEDED, State
from btcap.bt.tree import Tree
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation

__all__ = ["ECHO", "EchoLeaf", "implementations"]

ECHO = CapabilityInterface(
    "Echo",
    inputs={"value": int, "stop": Port(bool, False)},
    outputs={"value": int, "ticks": int, "robot": str},
    description="Echo an integer back every tick until told to stop.",
)


class EchoLeaf(Leaf):
    """Copies its input to its output each tick; done when ``stop`` or time is up."""

    __slots__ = ("_started", "_ticks")
    INPUTS: ClassVar[Any] = {"value": Port(int | None, None), "stop": Port(bool | None, False)}
    OUTPUTS: ClassVar[Any] = {"value": int, "ticks": int, "robot": str}
    OPTIONS: ClassVar[Any] = {"robot": Port(str, ""), "duration_s": Port(float, 0.0)}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._ticks = 0
        self._started: float | None = None
        super().__init__(*args, **kwargs)

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._started is None:
            self._started = now
        self._ticks += 1
        self.outputs["value"] = self.inputs["value"]
        self.outputs["ticks"] = self._ticks
        self.outputs["robot"] = self.options["robot"]
        duration = self.options["duration_s"]
        if self.inputs["stop"] or (duration > 0 and now - self._started >= duration):
            return SUCCEEDED
        return RUNNING

    def on_reset(self) -> None:
        self._ticks = 0
        self._started = None


def _build(robot: str, duration_s: float) -> Tree:
    inputs, outputs = ECHO.bridge_types()
    bridge_in = inputs(name="inputs")
    echo = EchoLeaf("echo", robot=robot, duration_s=duration_s)
    bridge_out = outputs(name="outputs")
    tree = Tree(ReactiveSequence("echo_impl", children=[bridge_in, echo, bridge_out]))
    tree.wire(bridge_in, "value", echo, "value")
    tree.wire(bridge_in, "stop", echo, "stop")
    for port in ("value", "ticks", "robot"):
        tree.wire(echo, port, bridge_out, port)
    return tree


def implementations(robot: str, cost: float = 1.0, duration_s: float = 0.0) -> list[Implementation]:
    """The Echo implementation of ``robot``, bidding ``cost``."""
    return [
        Implementation(
            f"echo-{robot}", ECHO, lambda: _build(robot, duration_s), bid=lambda _inputs: cost
        )
    ]
