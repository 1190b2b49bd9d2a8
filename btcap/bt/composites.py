"""Control flow: Sequence, Fallback, their reactive kinds, Parallel, IfThenElse.

The names mean what BehaviorTree.CPP v4 means. :class:`Sequence` and :class:`Fallback`
resume at their running child; :class:`SequenceWithMemory` also resumes at a child that
failed; :class:`ReactiveSequence` and :class:`ReactiveFallback` tick from their first child
every tick, so a condition that stops holding pre-empts the work after it. A child that is
UNASSIGNED, ASSIGNED or PAUSED counts as RUNNING, and a child in ERROR counts as FAILED
(the child keeps its error). A SKIPPED child (BehaviorTree.CPP's ``_skipIf``/``_while``)
is passed over as BehaviorTree.CPP 4.8 does, and a composite whose every child skipped
in one run is SKIPPED itself.

Halting: a composite that stops ticking an active child unticks it in that same tick, so
after every tick only nodes ticked in it are active (:mod:`btcap.bt.invariants` checks
this). Untick keeps progress (memory positions, a Parallel's finished children) and
:meth:`~btcap.bt.node.Node.reset` forgets it; see docs/trees.md for the rule.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.skipping import forget_skipped, memory_rest, reactive_rest
from btcap.bt.state import State, TreeError
from btcap.bt.utility import Utility, fallback_utility, parallel_utility, sequence_utility

__all__ = [
    "Composite",
    "Fallback",
    "IfThenElse",
    "Parallel",
    "ReactiveFallback",
    "ReactiveSequence",
    "Sequence",
    "SequenceWithMemory",
    "collapse",
    "halt_active",
]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR
_IDLE = State.IDLE
_SKIPPED = State.SKIPPED
#: ``ACTIVE`` as a tuple: ``in`` then compares by identity, without Enum's Python __hash__.
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def halt_active(node: Node) -> None:
    """Untick ``node`` if it has work in progress."""
    if node.state in _ACTIVE:
        node.untick()


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
            halt_active(children[i])
        self._high = index

    def on_reset(self) -> None:
        self._high = -1


class ReactiveSequence(Composite):
    """Succeeds when every child succeeds in order; starts from the first child every tick.

    It fails at the first failure. Because every tick starts again from the first child, a
    condition that stops holding pre-empts (unticks) a later child still running.
    """

    __slots__ = ()

    def on_tick(self) -> State:
        succeeded = _SUCCEEDED
        children = self.children
        for c in children:
            s = c.tick()
            if s is not succeeded:
                if s is _SKIPPED:
                    return reactive_rest(self, c, succeeded)
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


class ReactiveFallback(Composite):
    """Succeeds at the first child that succeeds; starts from the first child every tick.

    It fails when every child failed. Because every tick starts again from the first
    child, an earlier child that succeeds pre-empts (unticks) a later child still running.
    """

    __slots__ = ()

    def on_tick(self) -> State:
        failed, error = _FAILED, _ERROR
        children = self.children
        for c in children:
            s = c.tick()
            if s is not failed and s is not error:
                if s is _SKIPPED:
                    return reactive_rest(self, c, failed)
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
    """Resumes at the child it stopped at; the position survives an untick, not a reset."""

    __slots__ = ("_current",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._current = 0

    def on_reset(self) -> None:
        self._high = -1  # Composite.on_reset, inlined: resets are on a Parallel's tick path
        self._current = 0

    def _failed_at(self, i: int) -> None:
        """A memory sequence failed at child ``i``: the next run resumes there."""
        self._current = i
        forget_skipped(self.children, i)

    #: Whether the next run after a failure resumes at the failed child (SequenceWithMemory).
    _RESUME_FAILED: ClassVar[bool] = False
    #: Whether a child that gave its result at once ends the tick (AsyncSequence).
    _YIELDS: ClassVar[bool] = False


class Sequence(_Memory):
    """Succeeds when every child succeeds in order; resumes at the running child.

    As BehaviorTree.CPP's Sequence: the children before the running one, which succeeded,
    are not ticked again. It fails at the first failure; after a result the next tick
    starts at the first child.
    """

    __slots__ = ()

    def on_tick(self) -> State:
        children = self.children
        i = self._current
        n = len(children)
        while i < n:
            s = children[i].tick()
            if s is _SUCCEEDED:
                i += 1
            elif s is _FAILED or s is _ERROR:
                if self._RESUME_FAILED:
                    self._failed_at(i)
                else:
                    self._current = 0
                return _FAILED
            elif s is _SKIPPED:
                return memory_rest(self, i, _SUCCEEDED)
            else:
                self._current = i
                return _RUNNING
        self._current = 0
        return _SUCCEEDED

    def utility(self) -> Utility:
        return sequence_utility([c.utility() for c in self.children])


class SequenceWithMemory(Sequence):
    """A Sequence that, after a failure, resumes at the child that failed.

    As BehaviorTree.CPP's SequenceWithMemory: the children before the failed one are not
    ticked again. Only a success or a :meth:`~btcap.bt.node.Node.reset` (as a ``Retry``
    does before each new attempt) starts over at the first child. BehaviorTree.CPP halts
    the failed child and those after it; here none is active (a child that gave a result
    runs afresh when ticked again, and later ones were not ticked since the start).
    """

    __slots__ = ()
    _RESUME_FAILED: ClassVar[bool] = True


class Fallback(_Memory):
    """Succeeds at the first child that succeeds; resumes at the running child.

    As BehaviorTree.CPP's Fallback: the children before the running one, which failed,
    are not ticked again. It fails when every child failed; after a result the next tick
    starts at the first child.
    """

    __slots__ = ()

    def on_tick(self) -> State:
        children = self.children
        i = self._current
        n = len(children)
        while i < n:
            s = children[i].tick()
            if s is _FAILED or s is _ERROR:
                i += 1
            elif s is _SUCCEEDED:
                self._current = 0
                return _SUCCEEDED
            elif s is _SKIPPED:
                return memory_rest(self, i, _FAILED)
            else:
                self._current = i
                return _RUNNING
        self._current = 0
        return _FAILED

    def utility(self) -> Utility:
        return fallback_utility([c.utility() for c in self.children])


class Parallel(Composite):
    """Ticks every unfinished child each tick, then decides, as BehaviorTree.CPP's
    ``ParallelNode`` (v4) does:

    - it succeeds once ``success_threshold`` children have succeeded (default: all);
    - it fails once ``failure_threshold`` children have failed, or as soon as success has
      become impossible (default: only then);
    - when both are reached in the same tick, failure wins;
    - a negative threshold counts from the number of children: -1 is all, -2 all but one;
    - a threshold that can never be met is a :class:`TreeError` naming the node when the
      tree is validated, set up or loaded from a file;
    - once decided, children still running are unticked in that same tick.

    A finished child is not ticked again while the Parallel runs; an untick keeps those
    results. Ticked again after its own result, the Parallel starts over: children it
    halted (or that erred) are reset first, finished ones start afresh when ticked.
    """

    __slots__ = ("_bad", "_fail_at", "_need", "_ok", "_pending", "_restart", "_size")
    OPTIONS: ClassVar[Any] = {
        "success_threshold": Port(int, -1, "children that must succeed (negative: n + 1 + t)"),
        "failure_threshold": Port(
            int | None, None, "children whose failure fails it (default: when success is lost)"
        ),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._size = -1  # number of children the thresholds below were computed for
        self._need = self._fail_at = 0
        self._ok = self._bad = 0
        self._pending: list[Node] | None = None  # unfinished children; None: start afresh
        self._restart = False  # finished: reset the children before starting again

    def thresholds(self) -> tuple[int, int]:
        """(successes needed, failures that fail it) for the current children.

        Failing when success has become impossible is a failure count too, ``n - need + 1``,
        so the smaller of the two is returned. Raises TreeError if either can never be met.
        """
        n = len(self.children)
        ok = self.options["success_threshold"]
        need = ok if ok >= 0 else n + 1 + ok
        if not 0 <= need <= n:
            raise TreeError(
                f"node {self.path!r} (Parallel): success_threshold {ok} can never be met with "
                f"{n} children (expected {-n - 1}..{n})"
            )
        lost = n - need + 1
        bad = self.options["failure_threshold"]
        if bad is None:
            return need, lost
        fail_at = bad if bad >= 0 else n + 1 + bad
        if not 1 <= fail_at <= n:
            raise TreeError(
                f"node {self.path!r} (Parallel): failure_threshold {bad} can never be met with "
                f"{n} children (expected 1..{n} or -{n}..-1)"
            )
        return need, min(fail_at, lost)

    def check_children(self) -> None:
        self.thresholds()

    def on_setup(self) -> None:
        self.thresholds()

    def on_tick(self) -> State:
        children = self.children
        if len(children) != self._size:
            self._need, self._fail_at = self.thresholds()
            self._size = len(children)
        pending = self._pending
        if pending is None:
            if self._restart:  # children it halted (or that erred) start afresh, not resume
                for c in children:  # (idle ones have nothing to forget)
                    s = c.state
                    if s is not _SUCCEEDED and s is not _FAILED and s is not _IDLE:
                        c.reset()
                self._restart = False
            pending = children
            ok = bad = 0
        else:
            ok, bad = self._ok, self._bad
        running: list[Node] = []
        skipped = 0
        for c in pending:
            s = c.tick()
            if s is _SUCCEEDED:
                ok += 1
            elif s is _FAILED or s is _ERROR:
                bad += 1
            else:
                if s is _SKIPPED:  # not finished: ticked again next time, as in BT.CPP
                    skipped += 1
                running.append(c)
        if bad >= self._fail_at:
            result = _FAILED
        elif ok >= self._need:
            result = _SUCCEEDED
        elif skipped and self.options["success_threshold"] < 0 and ok + skipped >= self._need:
            result = _SUCCEEDED  # BehaviorTree.CPP 4.8: skipped children count for "all"
        else:
            self._pending, self._ok, self._bad = running, ok, bad
            return _SKIPPED if skipped == len(children) else _RUNNING
        for c in running:
            if c.state in _ACTIVE:
                c.untick()
        self._pending = None
        self._restart = True
        return result

    def on_reset(self) -> None:
        self._high = -1
        self._pending = None
        self._restart = False

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
            if otherwise is not None:
                halt_active(otherwise)
            return collapse(then.tick())
        if s is _FAILED or s is _ERROR:
            halt_active(then)
            return collapse(otherwise.tick()) if otherwise is not None else _FAILED
        # The condition is undecided: neither branch may keep working meanwhile.
        for branch in self.children[1:]:
            halt_active(branch)
        return _RUNNING

    def utility(self) -> Utility:
        return fallback_utility(
            [
                sequence_utility([c.utility() for c in self.children[:2]]),
                *(c.utility() for c in self.children[2:]),
            ]
        )


def collapse(s: State) -> State:
    """Map a child's state to what a composite reports for it."""
    if s is _SUCCEEDED:
        return s
    if s is _FAILED or s is _ERROR:
        return _FAILED
    return _RUNNING
