"""Decorators: one child, its result remapped, repeated, retried, timed or rate-limited.

Durations are clock seconds (see :class:`actors.Clock`), never wall-clock sleeps. A
decorator that gives a result while its child is still running unticks the child in that
same tick. Counts survive an untick and are forgotten on reset (docs/trees.md
states the rule for every node).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

from msgspec import Meta

from btcap.bt.host import wake
from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import State, TreeError
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
_SKIPPED = State.SKIPPED
#: ``ACTIVE`` as a tuple: ``in`` then compares by identity, without Enum's Python __hash__.
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def _result(s: State) -> State:
    """A child's state as the decorator sees it: ERROR counts as FAILED, waiting as RUNNING,
    SKIPPED stays SKIPPED."""
    if s is _SUCCEEDED or s is _FAILED:
        return s
    if s is _ERROR:
        return _FAILED
    return _SKIPPED if s is _SKIPPED else _RUNNING


class Decorator(Node):
    """A node with exactly one child."""

    __slots__ = ()
    MIN_CHILDREN: ClassVar[int] = 1
    MAX_CHILDREN: ClassVar[int | None] = 1
    #: True if the node leaves its running child unticked on some ticks by design (a
    #: Throttle between its child's ticks); the halting invariant allows that below it.
    HOLDS_RUNNING_CHILD: ClassVar[bool] = False

    def on_setup(self) -> None:
        if len(self.children) != 1:
            raise TreeError(f"{type(self).__name__} {self.name!r} needs exactly one child")

    @property
    def child(self) -> Node:
        return self.children[0]

    def utility(self) -> Utility:
        return self.children[0].utility() if self.children else Utility()


#: The ``on_tick`` functions made by :func:`_remapper`, so subclasses get their own.
_GENERATED: set[Callable[..., State]] = set()


def _remapper(table: dict[State, State]) -> Callable[[Remap], State]:
    """An ``on_tick`` for one MAP, with the outcomes bound (no lookup per tick). A SKIPPED
    child gives SKIPPED unless the MAP says otherwise (BehaviorTree.CPP 4.8's decorators)."""
    on_success, on_failure, on_running, on_skipped = (
        table.get(s, s) for s in (_SUCCEEDED, _FAILED, _RUNNING, _SKIPPED)
    )
    halts = on_running is not _RUNNING

    def on_tick(self: Remap) -> State:
        child = self.children[0]
        s = child.tick()
        if s is _SUCCEEDED:
            return on_success
        if s is _FAILED or s is _ERROR:
            return on_failure
        if s is _SKIPPED:
            return on_skipped
        if halts and s in _ACTIVE:
            child.untick()  # it counts as finished: nobody would tick or halt it later
        return on_running

    return on_tick


class Remap(Decorator):
    """Maps the child's succeeded/failed/running to other states (see the subclasses).

    When running is mapped to a result, the running child is unticked in that same tick:
    the parent takes the result as final and will neither tick nor halt the child later.
    """

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        inherited = cls.on_tick
        if inherited is Remap.on_tick or inherited in _GENERATED:  # not written by hand
            generated = _remapper(cls.MAP)
            _GENERATED.add(generated)
            cls.on_tick = generated  # type: ignore[method-assign,assignment]

    def on_tick(self) -> State:
        return _remapper(self.MAP)(self)


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
    """Do not wait for the child: running counts as success (and the child is unticked)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_RUNNING: _SUCCEEDED}


class RunningIsFailure(Remap):
    """Running counts as failure (and the child is unticked)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_RUNNING: _FAILED}


class SuccessIsRunning(Remap):
    """Keep a branch alive: success counts as running (so does a skipped child, as in
    BehaviorTree.CPP's KeepRunningUntilFailure)."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_SUCCEEDED: _RUNNING, _SKIPPED: _RUNNING}


class FailureIsRunning(Remap):
    """Failure counts as running."""

    __slots__ = ()
    MAP: ClassVar[dict[State, State]] = {_FAILED: _RUNNING}


class _Counting(Decorator):
    """Counts attempts; the count survives an untick (a paused branch resumes where it was)
    and is forgotten on reset or once the decorator gives its result. Starting another
    attempt after a child that finished at once, it asks to be ticked again at once
    (:func:`~btcap.bt.host.wake`, as BehaviorTree.CPP's RetryUntilSuccessful and Repeat)."""

    __slots__ = ("count",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.count = 0

    def on_reset(self) -> None:
        self.count = 0


class Retry(_Counting):
    """Re-runs a failing child up to ``retries`` more times; fails after that."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {
        "retries": Port(int, 1, "extra attempts after a failure", Meta(ge=0)),
    }

    def on_tick(self) -> State:
        child = self.children[0]
        instant = child.state not in _ACTIVE
        s = child.tick()
        if s is _SUCCEEDED:
            self.count = 0
            return s
        if s is not _FAILED and s is not _ERROR:
            return _RUNNING
        if self.count >= self.options["retries"]:
            self.count = 0
            return _FAILED
        self.count += 1
        child.reset()  # the next tick starts a fresh attempt
        if instant:
            wake(self)
        return _RUNNING


class Repeat(_Counting):
    """Runs a succeeding child ``times`` times (``-1``: forever); a failure fails it.

    ``times=0`` succeeds without ticking the child, as BehaviorTree.CPP's ``Repeat
    num_cycles="0"`` does.
    """

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {
        "times": Port(int, 1, "successes needed; -1 repeats forever", Meta(ge=-1)),
    }

    def on_tick(self) -> State:
        if not self.options["times"]:
            return _SUCCEEDED
        child = self.children[0]
        instant = child.state not in _ACTIVE
        s = child.tick()
        if s is not _SUCCEEDED:
            if s is _FAILED or s is _ERROR:
                self.count = 0
                return _FAILED
            return _SKIPPED if s is _SKIPPED else _RUNNING  # skipped: the count is kept
        self.count += 1
        times = self.options["times"]
        if 0 <= times <= self.count:
            self.count = 0
            return _SUCCEEDED
        child.reset()
        if instant:
            wake(self)
        return _RUNNING


#: A limit on attempts: None for none, else at least one (every run makes one).
_MAX_ATTEMPTS = Port(int | None, None, "give up after this many (None: never)", Meta(ge=1))


class RepeatUntilSuccess(_Counting):
    """Re-runs the child until it succeeds (at most ``max_attempts`` if given)."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"max_attempts": _MAX_ATTEMPTS}

    def on_tick(self) -> State:
        child = self.children[0]
        instant = child.state not in _ACTIVE
        s = _result(child.tick())
        if s is not _FAILED:
            if s is _SUCCEEDED:
                self.count = 0
            return s
        self.count += 1
        limit = self.options["max_attempts"]
        if limit is not None and self.count >= limit:
            self.count = 0
            return _FAILED
        child.reset()
        if instant:
            wake(self)
        return _RUNNING


class RepeatUntilFailure(_Counting):
    """Re-runs the child until it fails, then succeeds (at most ``max_attempts``)."""

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {"max_attempts": _MAX_ATTEMPTS}

    def on_tick(self) -> State:
        child = self.children[0]
        instant = child.state not in _ACTIVE
        s = _result(child.tick())
        if s is _FAILED:
            self.count = 0
            return _SUCCEEDED
        if s is _RUNNING or s is _SKIPPED:
            return s
        self.count += 1
        limit = self.options["max_attempts"]
        if limit is not None and self.count >= limit:
            self.count = 0
            return _FAILED
        child.reset()
        if instant:
            wake(self)
        return _RUNNING


class _Timed(Decorator):
    __slots__ = ("_since",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._since: float | None = None

    def on_reset(self) -> None:
        self._since = None


class Timeout(_Timed):
    """Fails (and unticks the child) if it has not finished within ``seconds``.

    On expiry the child is not ticked again (as BehaviorTree.CPP does). An untick restarts
    the period: time spent paused does not count against the child.
    """

    __slots__ = ()
    OPTIONS: ClassVar[Any] = {
        "seconds": Port(float, description="clock seconds allowed", meta=Meta(gt=0)),
    }

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is None:
            self._since = now
        if now - self._since >= self.options["seconds"]:
            child = self.children[0]
            if child.state in _ACTIVE:
                child.untick()
            self._since = None
            return _FAILED
        s = _result(self.children[0].tick())
        if s is _SUCCEEDED or s is _FAILED:
            self._since = None
        return s

    def on_untick(self) -> None:
        super().on_untick()
        self._since = None


class Delay(_Timed):
    """Waits ``seconds`` of clock time while ticked, then ticks the child.

    An untick keeps the time already waited, like any other progress: time spent
    unticked does not count, a later tick waits only for the rest. A reset forgets it.
    """

    __slots__ = ("_waited",)
    OPTIONS: ClassVar[Any] = {
        "seconds": Port(float, description="clock seconds to wait", meta=Meta(ge=0)),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._waited = 0.0  # waited before the last untick

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is None:
            self._since = now
        if self._waited + (now - self._since) < self.options["seconds"]:
            return _RUNNING
        s = _result(self.children[0].tick())
        if s is _SUCCEEDED or s is _FAILED:
            self._since = None
            self._waited = 0.0
        return s

    def on_untick(self) -> None:
        super().on_untick()
        if self._since is not None:
            self._waited += self.clock.now() - self._since
            self._since = None

    def on_reset(self) -> None:
        super().on_reset()
        self._waited = 0.0


class Throttle(_Timed):
    """Ticks the child at most ``rate_hz`` times per clock second, else repeats its state.

    Between its ticks a running child stays running, unticked: the Throttle holds it and
    unticks it when it is unticked itself.
    """

    __slots__ = ("_last",)
    HOLDS_RUNNING_CHILD: ClassVar[bool] = True
    OPTIONS: ClassVar[Any] = {
        "rate_hz": Port(float, description="ticks per clock second", meta=Meta(gt=0)),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._last = _RUNNING

    def on_tick(self) -> State:
        now = self.clock.now()
        if self._since is not None and now - self._since < 1.0 / self.options["rate_hz"]:
            return self._last
        self._since = now
        self._last = _result(self.children[0].tick())
        return self._last


class RunOnce(Decorator):
    """Runs the child to a result once, then keeps returning that result until reset
    (``forever``: a reset keeps it too, as BehaviorTree.CPP's RunOnce does), or SKIPPED
    with ``then_skip`` (BehaviorTree.CPP's default)."""

    __slots__ = ("_done",)
    OPTIONS: ClassVar[Any] = {
        "forever": Port(bool, False, "keep the result across resets"),
        "then_skip": Port(bool, False, "after the run, give SKIPPED instead of its result"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._done: State | None = None

    def on_tick(self) -> State:
        if self._done is not None:
            return _SKIPPED if self.options["then_skip"] else self._done
        s = _result(self.children[0].tick())
        if s is _SUCCEEDED or s is _FAILED:
            self._done = s
        return s

    def on_reset(self) -> None:
        if not self.options["forever"]:
            self._done = None
