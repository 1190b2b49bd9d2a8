"""Nav2's control and decorator nodes, deciding as Nav2's own (nav2_behavior_tree).

A Nav2 navigator's XML uses them; with ``--stub-missing`` a dry run builds these in
their place instead of a stand-in, so the run recovers only after a failure, replans at
the rate the file says, and so on. Each follows the rules of Nav2's C++ source
(``nav2_behavior_tree/plugins/control/*.cpp`` and ``plugins/decorator/*.cpp``):

- a halt (btcap's untick of the node while it runs) is Nav2's: the node forgets its
  position and counts, and its running children start afresh when next ticked
  (:func:`halt_child`);
- a skipped child (a BehaviorTree.CPP pre-condition's SKIPPED) counts as Nav2's
  sources at commit a3a97043 say: RecoveryNode is SKIPPED when its first child is, and
  fails, keeping its retries, when its recovery is; PipelineSequence and RoundRobin
  pass a skipped child over and are SKIPPED when every child was; RateController and
  SingleTrigger pass SKIPPED on.

Nav2's nodes that need the robot (``DistanceController``, ``SpeedController``,
``GoalUpdatedController``, ...) are not here: a dry run stands in for them and says so.
"""

from __future__ import annotations

from typing import Any, ClassVar

from btcap.bt.composites import Composite
from btcap.bt.decorators import Decorator
from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import State, TreeError

__all__ = [
    "NAV2_NODES",
    "NAV2_STOOD_IN",
    "PipelineSequence",
    "RateController",
    "RecoveryNode",
    "RoundRobin",
    "SingleTrigger",
    "halt_child",
]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR
_IDLE = State.IDLE
_PAUSED = State.PAUSED
_SKIPPED = State.SKIPPED
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def halt_child(child: Node) -> None:
    """BehaviorTree.CPP's ``haltChild``: a running (or paused) child is halted and starts
    afresh next time; a finished one only goes back to idle, keeping what it holds (a
    RoundRobin's turn), as BehaviorTree.CPP resets only the status of a node not running."""
    s = child.state
    if s in _ACTIVE or s is _PAUSED:
        if s is not _PAUSED:
            child.untick()
        child.reset()
    elif s is not _IDLE:
        child.untick()


def _failed(s: State) -> bool:
    return s is _FAILED or s is _ERROR


class _Nav2Control(Composite):
    """A Nav2 control node: a halt halts every child, as ``ControlNode::halt``."""

    __slots__ = ()

    def on_untick(self) -> None:
        if self.state in _ACTIVE:
            for c in self.children:
                halt_child(c)
            self.on_reset()


class RecoveryNode(_Nav2Control):
    """Nav2's RecoveryNode: ticks its first child; when that fails, ticks the second (the
    recovery) and, if the recovery succeeds, the first again, at most
    ``number_of_retries`` times. Fails when the recovery fails or the retries are spent;
    succeeds when the first child does (the recovery is then halted)."""

    __slots__ = ("_index", "_retries")
    MIN_CHILDREN: ClassVar[int] = 2
    MAX_CHILDREN: ClassVar[int | None] = 2
    INPUTS: ClassVar[Any] = {"number_of_retries": Port(int, 1, "recoveries to try")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._index = 0
        self._retries = 0

    def on_tick(self) -> State:
        limit = self.inputs["number_of_retries"]
        main, recovery = self.children
        while self._retries <= limit:
            if self._index == 0:
                s = main.tick()
                if s is _SUCCEEDED or s is _SKIPPED:
                    halt_child(recovery)
                    self._halt_all()
                    return s
                if not _failed(s):
                    return _RUNNING
                if self._retries >= limit:
                    break
                halt_child(main)
                self._index = 1
            else:
                s = recovery.tick()
                if s is _SUCCEEDED:
                    halt_child(recovery)
                    self._retries += 1
                    self._index = 0
                elif _failed(s):
                    break
                elif s is _SKIPPED:  # no recovery possible: fails, not a retry spent
                    self._index = 0
                    halt_child(recovery)
                    return _FAILED
                else:
                    return _RUNNING
        self._halt_all()
        return _FAILED

    def _halt_all(self) -> None:
        for c in self.children:
            halt_child(c)
        self.on_reset()

    def on_reset(self) -> None:
        self._high = -1
        self._index = 0
        self._retries = 0


class PipelineSequence(_Nav2Control):
    """Nav2's PipelineSequence: ticks every child from the first on each tick; a child
    that succeeded before is ticked again, and one that runs keeps running while a later
    one starts. It returns RUNNING at the first running child not before the furthest
    one reached, fails at the first failure, and succeeds when the last child does
    (halting all of them either way)."""

    __slots__ = ("_last",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._last = 0

    def on_tick(self) -> State:
        skipped = 0
        for i, c in enumerate(self.children):
            s = c.tick()
            if _failed(s):
                self._halt_all()
                return _FAILED
            if s is _SKIPPED:
                skipped += 1
            elif s is not _SUCCEEDED and i >= self._last:
                self._last = i
                return _RUNNING
        self._halt_all()
        return _SKIPPED if skipped == len(self.children) else _SUCCEEDED

    def _halt_all(self) -> None:
        for c in self.children:
            halt_child(c)
        self._last = 0

    def on_reset(self) -> None:
        self._high = -1
        self._last = 0


class RoundRobin(_Nav2Control):
    """Nav2's RoundRobin: ticks one child at a time, starting after the one that ran last;
    succeeds at the first child that succeeds (the next run starts after it), moves on
    after a failure, and fails once every child failed in turn. With ``wrap_around``
    false it also fails on reaching the last child."""

    __slots__ = ("_failures", "_index")
    MIN_CHILDREN: ClassVar[int] = 1
    INPUTS: ClassVar[Any] = {
        "wrap_around": Port(bool, False, "after the last child, go on with the first")
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._index = 0
        self._failures = 0

    def on_tick(self) -> State:
        children = self.children
        n = len(children)
        wrap = self.inputs["wrap_around"]
        skipped = 0
        while self._failures + skipped < n:
            s = children[self._index].tick()
            if s is _SUCCEEDED or s is _SKIPPED or _failed(s):
                self._index += 1
                if self._index == n:
                    if not wrap:
                        skipped += s is _SKIPPED
                        self._failures += _failed(s)
                        break
                    self._index = 0
            if s is _SUCCEEDED:
                self._failures = 0
                for c in children:
                    halt_child(c)
                return _SUCCEEDED
            if s is _SKIPPED:
                skipped += 1
                continue
            if not _failed(s):
                return _RUNNING
            self._failures += 1
        for c in children:
            halt_child(c)
        self.on_reset()
        return _SKIPPED if skipped == n else _FAILED

    def on_reset(self) -> None:
        self._high = -1
        self._index = 0
        self._failures = 0


class RateController(Decorator):
    """Nav2's RateController: ticks its child at most ``hz`` times a second (clock time).

    The child is ticked on the first tick after a halt, whenever it is running, and once
    a period has passed since it last succeeded (or since the start); between those
    ticks the node returns RUNNING without ticking it."""

    __slots__ = ("_first", "_start")
    INPUTS: ClassVar[Any] = {"hz": Port(float, 10.0, "ticks of the child per second")}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._start = 0.0
        self._first = True

    def on_tick(self) -> State:
        hz = self.inputs["hz"]
        if not hz > 0:
            raise TreeError(f"RateController {self.name!r}: hz must be > 0, got {hz}")
        now = self.clock.now()
        if self.state is _IDLE or self.state is _PAUSED:
            self._start = now
            self._first = True
        child = self.children[0]
        if not (self._first or child.state in _ACTIVE or now - self._start >= 1.0 / hz):
            return _RUNNING
        self._first = False
        s = child.tick()
        if s is _SUCCEEDED:
            self._start = now
        return _FAILED if s is _ERROR else s

    def on_untick(self) -> None:
        if self.state in _ACTIVE:
            halt_child(self.children[0])


class SingleTrigger(Decorator):
    """Nav2's SingleTrigger: ticks its child to one result, then fails on every tick
    until halted (unticked or reset)."""

    __slots__ = ("_first",)

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._first = True

    def on_tick(self) -> State:
        if self.state is _IDLE or self.state is _PAUSED:
            self._first = True
        if not self._first:
            return _FAILED
        s = self.children[0].tick()
        if s is _SUCCEEDED or _failed(s):
            self._first = False
            return _FAILED if s is _ERROR else s
        return s

    def on_untick(self) -> None:
        if self.state in _ACTIVE:
            halt_child(self.children[0])


#: Nav2's type names and their nodes here.
NAV2_NODES: dict[str, type[Node]] = {
    "RecoveryNode": RecoveryNode,
    "PipelineSequence": PipelineSequence,
    "RoundRobin": RoundRobin,
    "RateController": RateController,
    "SingleTrigger": SingleTrigger,
}

#: Nav2's control and decorator nodes not here: what each needs that a dry run lacks.
NAV2_STOOD_IN: dict[str, str] = {
    "DistanceController": "the robot's pose",
    "SpeedController": "the robot's odometry",
    "GoalUpdatedController": "the goal's updates",
    "GoalUpdater": "a goal topic",
    "PathLongerOnApproach": "the robot's pose and path",
    "PersistentSequence": "its blackboard index rules",
    "NonblockingSequence": "its rules, not yet modelled",
    "PauseResumeController": "ROS services",
}
