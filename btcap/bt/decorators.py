"""Decorators: one child, its result remapped, repeated, retried, timed or rate-limited.

Durations are clock seconds (see :class:`actors.Clock`), never wall-clock sleeps.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import ACTIVE, State, TreeError
from btcap.bt.utility import Utility

__all__ = [
    "Decorator",
    "Delay",
    "FailureIsRunning",
    "ForceFailure",
    "ForceSuccess",
    "Inverter",
    "Remap",
    "Repeat",
    "RepeatUntilFailure",
    "RepeatUntilSuccess",
    "Retry",
    "RunOnce",
    "RunningIsFailure",
    "RunningIsSuccess",
    "SuccessIsRunning",
    "Throttle",
    "Timeout",
]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR


def _result(s: State) -> State:
    """A child's state as the decorator sees it: ERROR counts as FAILED, waiting as RUNNING."""
    if s is _SUCCEEDED or s is _FAILED:
        return s
    return _FAILED if s is _ERROR else _RUNNING


class Decorator(Node):
    """A node with exactly one child."""

    __slots__ = ()
    MIN_CHILDREN: ClassVar[int] = 1
    MAX_CHILDREN: ClassVar[int | None] = 1

    def on_setup(self) -> None:
        if len(self.children) != 1:
            raise TreeError(f"{type(self).__name__} {self.name!r} needs exactly one child")

    @property
    def child(self) -> Node:
        return self.children[0]

    def utility(self) -> Utility:
        return self.children[0].utility() if self.children else Utility()


class Remap(Decorator):
    """Maps the child's succeeded/failed/running to other states (see the subclasses)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {}

    def on_tick(self) -> State:
        s = _result(self.children[0].tick())
        return self.MAP.get(s, s)


class Inverter(Remap):
    """Success becomes failure and vice versa."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_SUCCEEDED: _FAILED, _FAILED: _SUCCEEDED}


class ForceSuccess(Remap):
    """Failure becomes success (running stays running)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_FAILED: _SUCCEEDED}


class ForceFailure(Remap):
    """Success becomes failure (running stays running)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_SUCCEEDED: _FAILED}


class RunningIsSuccess(Remap):
    """Do not wait for the child: running counts as success."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_RUNNING: _SUCCEEDED}


class RunningIsFailure(Remap):
    """Running counts as failure."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_RUNNING: _FAILED}


class SuccessIsRunning(Remap):
    """Keep a branch alive: success counts as running."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_SUCCEEDED: _RUNNING}


class FailureIsRunning(Remap):
    """Failure counts as running."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_FAILED: _RUNNING}


class _Counting(Decorator):
    __slots__ = ("count",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.count = 0

    def on_reset(self) -> None:
        self.count = 0

    def _again(self) -> State:
        """Reset the child so the next tick starts it afresh."""
        self.children[0].reset()
        return _RUNNING


class Retry(_Counting):
    """Re-runs a failing child up to ``retries`` more times; fails after that."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"retries": Port(int, 1, "extra attempts after a failure")}

    def on_tick(self) -> State:
        s = _result(self.children[0].tick())
        if s is not _FAILED:
            if s is _SUCCEEDED:
                self.count = 0
            return s
        if self.count >= self.options["retries"]:
            self.count = 0
            return _FAILED
        self.count += 1
        return self._again()


class Repeat(_Counting):
    """Runs a succeeding child ``times`` times (``-1``: forever); a failure fails it."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"times": Port(int, 1, "successes needed; -1 repeats forever")}

    def on_tick(self) -> State:
        s = _result(self.children[0].tick())
        if s is not _SUCCEEDED:
            if s is _FAILED:
                self.count = 0
            return s
        self.count += 1
        times = self.options["times"]
        if 0 <= times <= self.count:
            self.count = 0
            return _SUCCEEDED
        return self._again()


class RepeatUntilSuccess(_Counting):
    """Re-runs the child until it succeeds (at most ``max_attempts`` if given)."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"max_attempts": Port(int | None, None, "give up after this many")}

    def on_tick(self) -> State:
        s = _result(self.children[0].tick())
        if s is not _FAILED:
            if s is _SUCCEEDED:
                self.count = 0
            return s
        self.count += 1
        limit = self.options["max_attempts"]
        if limit is not None and self.count >= limit:
            self.count = 0
            return _FAILED
        return self._again()


class RepeatUntilFailure(_Counting):
    """Re-runs the child until it fails, then succeeds (at most ``max_attempts``)."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"max_attempts": Port(int | None, None, "give up after this many")}

    def on_tick(self) -> State:
        s = _result(self.children[0].tick())
        if s is _FAILED:
            self.count = 0
            return _SUCCEEDED
        if s is _RUNNING:
            return s
        self.count += 1
        limit = self.options["max_attempts"]
        if limit is not None and self.count >= limit:
            self.count = 0
            return _FAILED
        return self._again()


class _Timed(Decorator):
    __slots__ = ("_since",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._since: float | None = None

    def on_reset(self) -> None:
        self._since = None


class Timeout(_Timed):
    """Fails (and unticks the child) if it has not finished within ``seconds``."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, description="clock seconds allowed")}

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is None:
            self._since = now
        if now - self._since >= self.options["seconds"]:
            child = self.children[0]
            if child.state in ACTIVE:
                child.untick()
            self._since = None
            return _FAILED
        s = _result(self.children[0].tick())
        if s is not _RUNNING:
            self._since = None
        return s

    def on_untick(self) -> None:
        super().on_untick()
        self._since = None


class Delay(_Timed):
    """Waits ``seconds`` after it is first ticked, then ticks the child."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"seconds": Port(float, description="clock seconds to wait")}

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is None:
            self._since = now
        if now - self._since < self.options["seconds"]:
            return _RUNNING
        s = _result(self.children[0].tick())
        if s is not _RUNNING:
            self._since = None
        return s


class Throttle(_Timed):
    """Ticks the child at most ``rate_hz`` times per clock second, else repeats its state."""

    __slots__ = ("_last",)
    OPTIONS: ClassVar[Any] = {"rate_hz": Port(float, description="ticks per clock second")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if self.options["rate_hz"] <= 0:
            raise TreeError(f"Throttle {self.name!r}: rate_hz must be > 0")
        self._last = _RUNNING

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is not None and now - self._since < 1.0 / self.options["rate_hz"]:
            return self._last
        self._since = now
        self._last = _result(self.children[0].tick())
        return self._last


class RunOnce(Decorator):
    """Runs the child to a result once, then keeps returning that result until reset."""

    __slots__ = ("_done",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._done: State | None = None

    def on_tick(self) -> State:
        if self._done is not None:
            return self._done
        s = _result(self.children[0].tick())
        if s is not _RUNNING:
            self._done = s
        return s

    def on_reset(self) -> None:
        self._done = None
