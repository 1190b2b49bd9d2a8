"""BehaviorTree.CPP's control nodes that give the tick back: AsyncSequence,
AsyncSequenceWithMemory, AsyncFallback, WhileDoElse; its IfThenElse, which latches, and
its ParallelAll, which waits for every child.

They exist so that a BehaviorTree.CPP file means in btcap what it means there (issue 20):

- :class:`AsyncSequence` and :class:`AsyncFallback` return RUNNING after a child that
  gave its result at once (it was not running before this tick), before ticking the next
  one. A reactive parent therefore re-checks its conditions between two instant
  children; ``ReactiveSequence[C, AsyncSequence[L0, L1]]`` fails on the second tick when
  ``C`` starts failing, where a plain Sequence would have run L0 and L1 in the first.
  A child that was running and now gives its result does not yield: the next child is
  ticked in the same tick. BehaviorTree.CPP 4.8's SequenceWithMemory yields the same way;
  it maps to :class:`AsyncSequenceWithMemory`. Yielding, they ask to be ticked again at
  once (:func:`~btcap.bt.host.wake`), which :meth:`Tree.tick_once
  <btcap.bt.tree.Tree.tick_once>` honours and :meth:`Tree.tick <btcap.bt.tree.Tree.tick>`
  leaves for the next tick.
- :class:`WhileDoElse` re-checks its condition every tick like :class:`IfThenElse`, but
  while the condition is RUNNING it returns RUNNING and leaves the branch that was
  running alone: not ticked, and not halted either (an IfThenElse unticks it). The branch
  keeps its background work, as an asynchronous BehaviorTree.CPP action keeps its thread.
  It is the one composite whose active children may go unticked for a tick
  (``HOLDS_RUNNING_CHILD``, which :mod:`btcap.bt.invariants` honours).
- :class:`LatchedIfThenElse` is BehaviorTree.CPP's IfThenElse: once the condition has
  given a result, only the chosen branch is ticked until it gives one; btcap's own
  :class:`IfThenElse` re-checks its condition every tick (BehaviorTree.CPP's WhileDoElse).
- :class:`ParallelAll` is BehaviorTree.CPP's ParallelAll: it ticks every unfinished child
  until all have finished, then fails if ``max_failures`` of them failed; btcap's
  :class:`~btcap.bt.composites.Parallel` decides as soon as a threshold is met.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.composites import Composite, Fallback, IfThenElse, Sequence
from btcap.bt.host import wake
from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.skipping import memory_rest
from btcap.bt.state import State, TreeError

__all__ = [
    "AsyncFallback",
    "AsyncSequence",
    "AsyncSequenceWithMemory",
    "LatchedIfThenElse",
    "ParallelAll",
    "WhileDoElse",
]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR
_SKIPPED = State.SKIPPED
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


class AsyncSequence(Sequence):
    """A Sequence that returns RUNNING after each child that succeeded at once.

    As BehaviorTree.CPP's AsyncSequence: the next child is ticked in the next tick, so a
    reactive parent can pre-empt between them. After the last child, or a child that was
    already running, there is nothing to yield for.
    """

    __slots__ = ()
    _YIELDS: ClassVar[bool] = True

    def on_tick(self) -> State:
        children = self.children
        i = self._current
        n = len(children)
        while i < n:
            child = children[i]
            instant = child.state not in _ACTIVE
            s = child.tick()
            if s is _SUCCEEDED:
                i += 1
                if instant and i < n:
                    self._current = i
                    wake(self)
                    return _RUNNING
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


class AsyncSequenceWithMemory(AsyncSequence):
    """An AsyncSequence that, after a failure, resumes at the child that failed.

    What BehaviorTree.CPP 4.8's ``SequenceWithMemory`` does: it yields like
    AsyncSequence (btcap's :class:`~btcap.bt.composites.SequenceWithMemory` does not),
    and a halt keeps its position, as an untick does here.
    """

    __slots__ = ()
    _RESUME_FAILED: ClassVar[bool] = True


class AsyncFallback(Fallback):
    """A Fallback that returns RUNNING after each child that failed at once.

    As BehaviorTree.CPP's AsyncFallback: the next child is ticked in the next tick.
    """

    __slots__ = ()
    _YIELDS: ClassVar[bool] = True

    def on_tick(self) -> State:
        children = self.children
        i = self._current
        n = len(children)
        while i < n:
            child = children[i]
            instant = child.state not in _ACTIVE
            s = child.tick()
            if s is _FAILED or s is _ERROR:
                i += 1
                if instant and i < n:
                    self._current = i
                    wake(self)
                    return _RUNNING
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


class WhileDoElse(IfThenElse):
    """An IfThenElse whose running branch keeps running while the condition runs.

    The condition is ticked every tick; then the second child if it succeeded, else the
    third (if any). As BehaviorTree.CPP's WhileDoElse. Without a third child, a failed
    condition fails the node (and halts the second child).
    """

    __slots__ = ()
    #: A running branch stays active, unticked, while the condition runs.
    HOLDS_RUNNING_CHILD: ClassVar[bool] = True

    def on_tick(self) -> State:
        children = self.children
        s = children[0].tick()
        if s is _FAILED or s is _ERROR:
            _halt(children[1])
            if len(children) < 3:
                return _FAILED
            return _result(children[2].tick())
        if s is _SUCCEEDED:
            if len(children) > 2:
                _halt(children[2])
            return _result(children[1].tick())
        if s is _SKIPPED:
            _skipped_condition(self)
        return _RUNNING


class LatchedIfThenElse(Composite):
    """Ticks the condition until it decides, then only the chosen branch until it ends.

    The branch is the second child on success, else the third. As BehaviorTree.CPP's
    IfThenElse. Without a third child, a failed condition fails the node. The chosen
    branch is progress: it survives an untick, not a reset.
    """

    __slots__ = ("_branch",)
    MIN_CHILDREN: ClassVar[int] = 2
    MAX_CHILDREN: ClassVar[int | None] = 3

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._branch = 0  # 0: the condition decides next; else the branch running

    def check_children(self) -> None:
        if len(self.children) < 2:
            raise TreeError(
                f"{type(self).__name__} {self.name!r} needs a condition and a then-branch"
            )

    def on_setup(self) -> None:
        self.check_children()

    def on_tick(self) -> State:
        children = self.children
        if self._branch == 0:
            s = children[0].tick()
            if s is _SUCCEEDED:
                self._branch = 1
            elif s is _FAILED or s is _ERROR:
                if len(children) < 3:
                    return _FAILED
                self._branch = 2
            else:
                if s is _SKIPPED:
                    _skipped_condition(self)
                return _RUNNING
        s = _result(children[self._branch].tick())
        if s is not _RUNNING:  # a result, or SKIPPED: BehaviorTree.CPP starts over too
            self._branch = 0
        return s

    def on_reset(self) -> None:
        super().on_reset()
        self._branch = 0


class ParallelAll(Composite):
    """Ticks every unfinished child until all finish; fails if ``max_failures`` failed.

    A negative ``max_failures`` counts from the number of children (-1 is all). As
    BehaviorTree.CPP's ParallelAll. The finished children are progress: they survive
    an untick, not a reset.
    """

    __slots__ = ("_failures", "_finished")
    OPTIONS: ClassVar[Any] = {
        "max_failures": Port(int, 1, "failures that fail it once all children finished"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._finished: set[int] = set()
        self._failures = 0

    def threshold(self) -> int:
        """Failures that fail it, for the current children; TreeError if never met."""
        n = len(self.children)
        t: int = self.options["max_failures"]
        at = max(n + t + 1, 0) if t < 0 else t
        if at > n:
            raise TreeError(
                f"node {self.path!r} (ParallelAll): max_failures {t} can never be met with "
                f"{n} children"
            )
        return at

    def check_children(self) -> None:
        self.threshold()

    def on_setup(self) -> None:
        self.threshold()

    def on_tick(self) -> State:
        finished = self._finished
        skipped = 0
        for i, child in enumerate(self.children):
            if i in finished:
                continue
            s = child.tick()
            if s is _SUCCEEDED:
                finished.add(i)
            elif s is _FAILED or s is _ERROR:
                finished.add(i)
                self._failures += 1
            elif s is _SKIPPED:
                skipped += 1
        if skipped:  # BehaviorTree.CPP 4.8: every child skipped it, or skipped ones finish it
            if skipped == len(self.children):
                return _SKIPPED
            if skipped + len(finished) >= len(self.children):
                failed = self._failures >= self.threshold()
                self.on_reset()
                return _FAILED if failed else _SUCCEEDED
            return _RUNNING
        if len(finished) < len(self.children):
            return _RUNNING
        failed = self._failures >= self.threshold()
        self.on_reset()
        return _FAILED if failed else _SUCCEEDED

    def on_reset(self) -> None:
        self._finished = set()
        self._failures = 0


def _skipped_condition(node: Node) -> None:
    """A skipped condition leaves nothing to choose: BehaviorTree.CPP 4.8 throws (a logic
    error in IfThenElse, a child returning IDLE after WhileDoElse); so does this tick."""
    raise TreeError(
        f"node {node.path!r} ({type(node).__name__}): its condition was skipped "
        f"(_skipIf/_while), which leaves no branch to run; BehaviorTree.CPP throws here too"
    )


def _halt(node: Node) -> None:
    if node.state in _ACTIVE:
        node.untick()


def _result(s: State) -> State:
    if s is _SUCCEEDED:
        return s
    if s is _FAILED or s is _ERROR:
        return _FAILED
    return _SKIPPED if s is _SKIPPED else _RUNNING
