"""Retry, Repeat, Timeout, Delay and Wait taking their count or duration from an input.

BehaviorTree.CPP's built-ins read these from a port, so a file may give them from the
blackboard (``<RetryUntilSuccessful num_attempts="{n}">``); btcap's own nodes take them
as options fixed when the tree is built. These variants have BehaviorTree.CPP's port
names and units (milliseconds) and read the input when BehaviorTree.CPP 4.8 does
(its ``retry_node.cpp``, ``repeat_node.cpp``, ``timeout_node.cpp``, ``delay_node.cpp``,
``sleep_node.cpp``):

- ``num_attempts`` and ``num_cycles`` on every tick, ``num_attempts`` again after each
  failed attempt (-1: no limit; once the count is reached, or for 0 or another negative
  count, the result comes at once without ticking the child: failure for a retry,
  success for a repeat);
- ``msec`` of a Timeout when its timer starts (0: no time limit), ``delay_msec`` of a
  Delay when its wait starts, ``msec`` of a Sleep (btcap's Wait) when it starts.

One difference: when a retry finds its count already reached while its child is running
(a child lowered it), BehaviorTree.CPP fails without halting the child, which stays
running; btcap halts it.

The XML reader picks them only where the attribute names an entry, so a tree with
literal options ticks btcap's own nodes.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from btcap.bt.decorators import Delay, Repeat, RepeatUntilSuccess, Timeout
from btcap.bt.host import wake
from btcap.bt.leaves import Wait
from btcap.bt.ports import Port
from btcap.bt.state import State, TreeError

__all__ = [
    "DelayFromInput",
    "RepeatFromInput",
    "RepeatUntilSuccessFromInput",
    "TimeoutFromInput",
    "WaitFromInput",
]

_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def _whole(node: Any, key: str) -> int:
    """The input as a whole number (text and integral floats converted, as BT.CPP does)."""
    value = node.inputs[key]
    if type(value) is int:
        return value
    try:
        if isinstance(value, str):
            return int(value.strip())
        if isinstance(value, float) and value.is_integer():
            return int(value)
    except ValueError:
        pass
    raise TreeError(f"node {node.path!r} input {key!r}: expected a whole number, got {value!r}")


def _msec(node: Any, key: str) -> float:
    """The input in milliseconds as seconds; a negative one is refused."""
    ms = _whole(node, key)
    if ms < 0:
        raise TreeError(f"node {node.path!r} input {key!r}: expected milliseconds >= 0, got {ms}")
    return ms / 1000.0


def _stop_child(node: Any) -> None:
    child = node.children[0]
    if child.state in _ACTIVE:
        child.untick()


class RepeatUntilSuccessFromInput(RepeatUntilSuccess):
    """BehaviorTree.CPP's RetryUntilSuccessful with ``num_attempts`` read on every tick
    and again after each failed attempt (a child may change it)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"num_attempts": Port(int, description="attempts; -1: no limit")}

    def _more(self) -> bool:
        n = _whole(self, "num_attempts")
        self.options["max_attempts"] = None if n == -1 else n
        return self.count < n or n == -1

    def on_tick(self) -> State:
        if not self._more():
            _stop_child(self)
            self.count = 0
            return State.FAILED
        child = self.children[0]
        instant = child.state not in _ACTIVE
        s = child.tick()
        if s is State.SUCCEEDED:
            self.count = 0
            return s
        if s is not State.FAILED and s is not State.ERROR:
            return State.RUNNING
        self.count += 1
        for key, board, entry in self._pulls or ():  # what the attempt may have written
            if key == "num_attempts":
                self.inputs[key] = board.outputs[entry]
        if not self._more():
            self.count = 0
            return State.FAILED
        child.reset()
        if instant:
            wake(self)
        return State.RUNNING


class RepeatFromInput(Repeat):
    """BehaviorTree.CPP's Repeat with ``num_cycles`` read on every tick."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"num_cycles": Port(int, description="cycles; -1: forever")}
    OPTIONS: ClassVar[Any] = {"times": Port(int, 1, "set from num_cycles on every tick")}

    def on_tick(self) -> State:
        n = _whole(self, "num_cycles")
        if n < -1:
            _stop_child(self)
            self.count = 0
            return State.SUCCEEDED
        self.options["times"] = n
        return super().on_tick()


class TimeoutFromInput(Timeout):
    """BehaviorTree.CPP's Timeout with ``msec`` read when its timer starts (0: no limit)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"msec": Port(int, description="milliseconds; 0: no limit")}
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, math.inf, "set from msec at the start")}

    def on_tick(self) -> State:
        if self._since is None:
            self.options["seconds"] = _msec(self, "msec") or math.inf
        return super().on_tick()


class DelayFromInput(Delay):
    """BehaviorTree.CPP's Delay with ``delay_msec`` read when its wait starts."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"delay_msec": Port(int, description="milliseconds to wait")}
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, 0.0, "set from delay_msec at the start")}

    def on_tick(self) -> State:
        if self._since is None and self._waited == 0.0:
            self.options["seconds"] = _msec(self, "delay_msec")
        return super().on_tick()


class WaitFromInput(Wait):
    """BehaviorTree.CPP's Sleep: btcap's Wait with ``msec`` read when it starts."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"msec": Port(int, description="milliseconds to wait")}
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, 0.0, "set from msec at the start")}

    def on_tick(self) -> State:
        if self._until is None:
            self.options["seconds"] = _msec(self, "msec")
        return super().on_tick()
