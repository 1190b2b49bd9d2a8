"""Control flow: Sequence, Fallback (reactive and with memory), Parallel, IfThenElse, Switch.

Reactive composites tick from their first child every tick, so a condition that stops
holding pre-empts the work after it. Children that were active and are no longer ticked
are unticked. A child that is UNASSIGNED, ASSIGNED or PAUSED counts as RUNNING, and a
child in ERROR counts as FAILED (the child keeps its error for inspection).
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import ACTIVE, State, TreeError
from btcap.bt.utility import Utility, fallback_utility, parallel_utility, sequence_utility

__all__ = [
    "Fallback",
    "FallbackWithMemory",
    "IfThenElse",
    "Parallel",
    "Sequence",
    "SequenceWithMemory",
    "Switch",
]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR
_IDLE = State.IDLE


class Composite(Node):
    """A node with any number of children."""

    __slots__ = ("_high",)
    MAX_CHILDREN: ClassVar[int | None] = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._high = -1  # highest child index ticked in the previous tick

    def _halt_after(self, index: int) -> None:
        """Untick children after ``index`` that were ticked last time and are still active."""
        children = self.children
        for i in range(index + 1, min(self._high, len(children) - 1) + 1):
            c = children[i]
            if c.state in ACTIVE:
                c.untick()
        self._high = index

    def on_reset(self) -> None:
        self._high = -1


class Sequence(Composite):
    """Succeeds when every child succeeds, in order; fails at the first failure."""

    __slots__ = ()

    def on_tick(self) -> State:
        succeeded = _SUCCEEDED
        children = self.children
        for c in children:
            s = c.tick()
            if s is not succeeded:
                break
        else:
            self._high = len(children) - 1
            return succeeded
        i = children.index(c)  # identity: nodes do not define __eq__
        if self._high > i:
            self._halt_after(i)
        else:
            self._high = i
        return _FAILED if s is _FAILED or s is _ERROR else _RUNNING

    def utility(self) -> Utility:
        return sequence_utility([c.utility() for c in self.children])


class Fallback(Composite):
    """Succeeds at the first child that succeeds; fails when every child failed."""

    __slots__ = ()

    def on_tick(self) -> State:
        failed, error = _FAILED, _ERROR
        children = self.children
        for c in children:
            s = c.tick()
            if s is not failed and s is not error:
                break
        else:
            self._high = len(children) - 1
            return failed
        i = children.index(c)  # identity: nodes do not define __eq__
        if self._high > i:
            self._halt_after(i)
        else:
            self._high = i
        return _SUCCEEDED if s is _SUCCEEDED else _RUNNING

    def utility(self) -> Utility:
        return fallback_utility([c.utility() for c in self.children])


class _Memory(Composite):
    __slots__ = ("_current",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._current = 0

    def on_reset(self) -> None:
        super().on_reset()
        self._current = 0

    def _step(self, stop_on: State, done: State, other: State) -> State:
        children = self.children
        while self._current < len(children):
            s = children[self._current].tick()
            if s is _ERROR:
                s = _FAILED
            if s is stop_on:
                self._current = 0
                return stop_on
            if s is done:
                self._current += 1
                continue
            return _RUNNING
        self._current = 0
        return other


class SequenceWithMemory(_Memory):
    """Like :class:`Sequence`, but children that succeeded are not ticked again."""

    __slots__ = ()

    def on_tick(self) -> State:
        return self._step(_FAILED, _SUCCEEDED, _SUCCEEDED)

    def utility(self) -> Utility:
        return sequence_utility([c.utility() for c in self.children])


class FallbackWithMemory(_Memory):
    """Like :class:`Fallback`, but children that failed are not ticked again."""

    __slots__ = ()

    def on_tick(self) -> State:
        return self._step(_SUCCEEDED, _FAILED, _FAILED)

    def utility(self) -> Utility:
        return fallback_utility([c.utility() for c in self.children])


class Parallel(Composite):
    """Ticks all unfinished children each tick.

    Succeeds once ``success_threshold`` children succeeded (default: all of them); fails
    once ``failure_threshold`` children failed (default: as soon as success has become
    impossible). Children still running at that point are unticked; the finished ones
    are reset when the Parallel is ticked again afterwards.
    """

    __slots__ = ("_results",)
    OPTIONS: ClassVar[Any] = {
        "success_threshold": Port(int | None, None, "children that must succeed (default all)"),
        "failure_threshold": Port(int | None, None, "children whose failure fails it"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._results: list[State | None] = []

    def _thresholds(self) -> tuple[int, int]:
        n = len(self.children)
        ok = self.options["success_threshold"]
        ok = n if ok is None else ok
        bad = self.options["failure_threshold"]
        bad = n - ok + 1 if bad is None else bad
        if not 0 <= ok <= n or bad < 1:
            raise TreeError(
                f"Parallel {self.name!r}: success_threshold must be within 0..{n} and "
                f"failure_threshold >= 1 (got {ok}, {bad})"
            )
        return ok, bad

    def on_setup(self) -> None:
        self._thresholds()

    def on_tick(self) -> State:
        ok_needed, bad_needed = self._thresholds()
        children = self.children
        if len(self._results) != len(children) or all(r is not None for r in self._results):
            if any(r is not None for r in self._results):
                for c in children:
                    c.reset()
            self._results = [None] * len(children)
        results = self._results
        ok = bad = 0
        for i, c in enumerate(children):
            r = results[i]
            if r is None:
                s = c.tick()
                if s is _SUCCEEDED or s is _FAILED or s is _ERROR:
                    r = results[i] = _FAILED if s is _ERROR else s
            if r is _SUCCEEDED:
                ok += 1
            elif r is _FAILED:
                bad += 1
        if ok >= ok_needed or bad >= bad_needed:
            for c in children:
                if c.state in ACTIVE:
                    c.untick()
            self._results = [_SUCCEEDED] * len(children)
            return _SUCCEEDED if ok >= ok_needed else _FAILED
        return _RUNNING

    def on_reset(self) -> None:
        super().on_reset()
        self._results = []

    def utility(self) -> Utility:
        return parallel_utility([c.utility() for c in self.children])


class IfThenElse(Composite):
    """Ticks the first child; then the second if it succeeded, else the third (if any).

    Reactive: the condition is ticked every tick; the branch not taken is unticked, and so
    are both while the condition is still running. Without a third child, a failed
    condition fails the node.
    """

    __slots__ = ()
    MIN_CHILDREN: ClassVar[int] = 2
    MAX_CHILDREN: ClassVar[int | None] = 3

    def on_setup(self) -> None:
        if len(self.children) < 2:
            raise TreeError(f"IfThenElse {self.name!r} needs a condition and a then-branch")

    def on_tick(self) -> State:
        cond, then, *rest = self.children
        otherwise = rest[0] if rest else None
        s = cond.tick()
        if s is _SUCCEEDED:
            if otherwise is not None and otherwise.state in ACTIVE:
                otherwise.untick()
            return _collapse(then.tick())
        if s is _FAILED or s is _ERROR:
            if then.state in ACTIVE:
                then.untick()
            return _collapse(otherwise.tick()) if otherwise is not None else _FAILED
        # The condition is undecided: neither branch may keep working meanwhile.
        for branch in self.children[1:]:
            if branch.state in ACTIVE:
                branch.untick()
        return _RUNNING

    def utility(self) -> Utility:
        return fallback_utility(
            [
                sequence_utility([c.utility() for c in self.children[:2]]),
                *(c.utility() for c in self.children[2:]),
            ]
        )


class Switch(Composite):
    """Ticks the child whose case equals the ``value`` input; the last child is the default.

    ``cases`` lists one value per child (``len(cases) == len(children)``) or one fewer,
    in which case the last child runs when no case matches; otherwise no match fails.
    """

    __slots__ = ("_active",)
    INPUTS: ClassVar[Any] = {"value": Port(Any, None, "the value to switch on")}
    OPTIONS: ClassVar[Any] = {"cases": Port(list[Any], description="one value per child")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._active: Node | None = None

    def on_setup(self) -> None:
        n, k = len(self.children), len(self.options["cases"])
        if k not in (n, n - 1):
            raise TreeError(
                f"Switch {self.name!r}: {k} cases for {n} children; expected {n} or {n - 1}"
            )

    def on_tick(self) -> State:
        value = self.inputs["value"]
        cases: list[Any] = self.options["cases"]
        children = self.children
        try:
            chosen: Node | None = children[cases.index(value)]
        except ValueError:
            chosen = children[-1] if len(cases) < len(children) else None
        if self._active is not None and self._active is not chosen and self._active.state in ACTIVE:
            self._active.untick()
        self._active = chosen
        if chosen is None:
            return _FAILED
        return _collapse(chosen.tick())

    def on_reset(self) -> None:
        super().on_reset()
        self._active = None

    def utility(self) -> Utility:
        return fallback_utility([c.utility() for c in self.children])


def _collapse(s: State) -> State:
    """Map a child's state to what a composite reports for it."""
    if s is _SUCCEEDED:
        return s
    if s is _FAILED or s is _ERROR:
        return _FAILED
    return _RUNNING
