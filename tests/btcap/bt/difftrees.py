"""Random trees built alike in btcap and py_trees 2.x, for the differential test.

A tree is a :class:`Spec`: composites (Sequence/Fallback, which resume at the running
child, as py_trees' ``memory=True``; ReactiveSequence/ReactiveFallback, as ``memory=False``;
SequenceWithMemory; Parallel with thresholds), decorators (Inverter, Retry, Repeat,
Timeout, ForceSuccess/Failure, RunningIsSuccess/Failure) and scripted leaves whose
result at tick ``t`` is ``script[t % len(script)]``. Both builds log the leaves they tick
and the leaves they halt (a running leaf unticked / stopped to INVALID) into one
:class:`Log` per library.

py_trees is the oracle except where btcap differs on purpose. Those differences are
modelled here, each in one small py_trees class, so every other difference shows:

- untick keeps progress: a Sequence/Fallback halted while running resumes at its child
  (:class:`KeepSequence`/:class:`KeepSelector`), Retry/Repeat keep their counts
  (:class:`KeepRetry`/:class:`KeepRepeat`), a Parallel keeps its finished children; a
  btcap ``reset`` (Retry/Repeat starting an attempt afresh, a Parallel starting over with
  the children it halted) forgets it (:func:`forget`);
- SequenceWithMemory, which py_trees lacks, is BehaviorTree.CPP's: after a failure it
  resumes at the child that failed (:class:`ResumeFailedSequence`);
- Timeout fails on expiry without ticking the child, as BehaviorTree.CPP does; its
  period restarts after a halt (:class:`BtcapTimeout`);
- Parallel follows BehaviorTree.CPP's ParallelNode v4 thresholds, failure winning a tie
  (:class:`ThresholdParallel`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import hypothesis.strategies as st
import py_trees
from py_trees.common import Status

import btcap
from btcap import State

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING
COMPOSITES = ("rseq", "rfb", "seq", "fb", "swm", "par")
DECORATORS = ("inv", "retry", "repeat", "timeout", "force_s", "force_f", "run_s", "run_f")
_STATUS = {S: Status.SUCCESS, F: Status.FAILURE, R: Status.RUNNING}
STATE_OF = {v: k for k, v in _STATUS.items()}


@dataclass(frozen=True)
class Spec:
    kind: str  # a composite, a decorator or "leaf"
    name: str
    children: tuple[Spec, ...] = ()
    script: tuple[State, ...] = ()
    arg: int = 0  # retries, times, timeout seconds
    need: int = -1  # Parallel success_threshold
    fail: int | None = None  # Parallel failure_threshold

    def walk(self) -> Iterator[Spec]:
        yield self
        for c in self.children:
            yield from c.walk()


@st.composite
def specs(draw: st.DrawFn, depth: int = 0, name: str = "r", max_depth: int = 5) -> Spec:
    """A tree of depth at most ``max_depth`` and fan-out at most 4."""
    if depth == max_depth or draw(st.integers(0, 9)) < 2 + depth:
        script = draw(st.lists(st.sampled_from([S, F, R]), min_size=1, max_size=5))
        return Spec("leaf", name, script=tuple(script))
    if draw(st.integers(0, 2)) == 0:
        kind = draw(st.sampled_from(DECORATORS))
        child = draw(specs(depth + 1, f"{name}_0", max_depth))
        arg = {"retry": (0, 2), "repeat": (1, 3), "timeout": (1, 3)}.get(kind, (0, 0))
        return Spec(kind, name, (child,), arg=draw(st.integers(*arg)))
    kind = draw(st.sampled_from(COMPOSITES))
    n = draw(st.integers(1, 4))
    kids = tuple(draw(specs(depth + 1, f"{name}_{i}", max_depth)) for i in range(n))
    if kind != "par":
        return Spec(kind, name, kids)
    need = draw(st.integers(-n - 1, n))
    fail = draw(st.none() | st.integers(1, n) | st.integers(-n, -1))
    return Spec(kind, name, kids, need=need, fail=fail)


@dataclass
class Log:
    """What one library did in one tick."""

    ticked: list[str] = field(default_factory=list)
    halted: list[str] = field(default_factory=list)


class TickClock:
    """Clock seconds = the tick number, set by the test before each tick."""

    speedup = 1.0

    def __init__(self) -> None:
        self.t = 0

    def now(self) -> float:
        return float(self.t)

    def to_wall(self, seconds: float) -> float:
        return seconds

    async def sleep(self, seconds: float) -> None:
        raise AssertionError("the differential test never sleeps")

    async def sleep_until(self, deadline: float) -> None:
        raise AssertionError("the differential test never sleeps")


# -- btcap --------------------------------------------------------------------------------


class Scripted(btcap.Leaf):
    def __init__(self, name: str, script: tuple[State, ...], log: Log, clock: TickClock) -> None:
        super().__init__(name)
        self.script, self.log, self.clock_ = script, log, clock

    def on_tick(self) -> State:
        self.log.ticked.append(self.name)
        return self.script[self.clock_.t % len(self.script)]

    def on_untick(self) -> None:
        if self.state in (R, State.ASSIGNED, State.UNASSIGNED):
            self.log.halted.append(self.name)


def build_btcap(spec: Spec, log: Log, clock: TickClock) -> btcap.Node:
    if spec.kind == "leaf":
        return Scripted(spec.name, spec.script, log, clock)
    kids = [build_btcap(c, log, clock) for c in spec.children]
    k, name = spec.kind, spec.name
    simple: dict[str, type[btcap.Node]] = {
        "rseq": btcap.ReactiveSequence,
        "rfb": btcap.ReactiveFallback,
        "seq": btcap.Sequence,
        "fb": btcap.Fallback,
        "swm": btcap.SequenceWithMemory,
        "inv": btcap.Inverter,
        "force_s": btcap.ForceSuccess,
        "force_f": btcap.ForceFailure,
        "run_s": btcap.RunningIsSuccess,
        "run_f": btcap.RunningIsFailure,
    }
    if k in simple:
        return simple[k](name, children=kids)
    if k == "par":
        return btcap.Parallel(
            name, children=kids, success_threshold=spec.need, failure_threshold=spec.fail
        )
    if k == "retry":
        return btcap.Retry(name, children=kids, retries=spec.arg)
    if k == "repeat":
        return btcap.Repeat(name, children=kids, times=spec.arg)
    assert k == "timeout"
    return btcap.Timeout(name, children=kids, seconds=float(spec.arg))


# -- py_trees, with btcap's deliberate differences modelled --------------------------------


def forget(b: py_trees.behaviour.Behaviour) -> None:
    """What a btcap ``reset`` does to progress kept below ``b``: it is gone."""
    for node in b.iterate():
        if isinstance(node, Keeps):
            node.forget()


class Keeps:
    """A py_trees behaviour that, like btcap, keeps its progress when halted."""

    def forget(self) -> None:
        raise NotImplementedError


class PtLeaf(py_trees.behaviour.Behaviour):
    def __init__(self, name: str, script: tuple[State, ...], log: Log, clock: TickClock) -> None:
        super().__init__(name)
        self.script = tuple(_STATUS[s] for s in script)
        self.log, self.clock = log, clock

    def update(self) -> Status:
        self.log.ticked.append(self.name)
        return self.script[self.clock.t % len(self.script)]

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.log.halted.append(self.name)


class _KeepPosition(Keeps):
    """A memory composite halted while running resumes at the child it was at."""

    resume: int | None = None
    children: list[py_trees.behaviour.Behaviour]
    current_child: py_trees.behaviour.Behaviour | None
    status: Status

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            assert self.current_child is not None
            self.resume = self.children.index(self.current_child)
        super().stop(new_status)

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.resume is not None:
            self.current_child = self.children[self.resume]
            self.status, self.resume = Status.RUNNING, None
        yield from super().tick()

    def forget(self) -> None:
        self.resume = None


class KeepSequence(_KeepPosition, py_trees.composites.Sequence):
    pass


class KeepSelector(_KeepPosition, py_trees.composites.Selector):
    pass


class ResumeFailedSequence(KeepSequence):
    """BehaviorTree.CPP's SequenceWithMemory: after a failure the next tick resumes at the
    child that failed; only a success or a reset (:func:`forget`) starts over."""

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.FAILURE:
            assert self.current_child is not None
            self.resume = self.children.index(self.current_child)
        super().stop(new_status)


class _KeepCount(Keeps):
    """Retry/Repeat halted while running keep their count; each new attempt starts from
    a reset child (btcap resets it, so progress kept deep inside is forgotten too)."""

    halted = False
    status: Status
    decorated: py_trees.behaviour.Behaviour

    def initialise(self) -> None:
        if self.halted:
            self.halted = False
            return
        super().initialise()

    def stop(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING:
            self.halted = True
        super().stop(new_status)

    def update(self) -> Status:
        result: Status = super().update()
        if result == Status.RUNNING and self.decorated.status != Status.RUNNING:
            forget(self.decorated)  # another attempt / repetition: btcap resets the child
        return result

    def forget(self) -> None:
        self.halted = False
        super().initialise()


class KeepRetry(_KeepCount, py_trees.decorators.Retry):
    pass


class KeepRepeat(_KeepCount, py_trees.decorators.Repeat):
    pass


class BtcapTimeout(Keeps, py_trees.decorators.Decorator):
    """Fails once ``seconds`` have passed since its period began, without ticking the
    child; a halt restarts the period."""

    def __init__(self, name: str, child: Any, seconds: int, clock: TickClock) -> None:
        super().__init__(name, child)
        self.seconds, self.clock = seconds, clock
        self.since: int | None = None

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        now = self.clock.t
        if self.since is None:
            self.since = now
        if now - self.since >= self.seconds:
            self.since = None
            self.stop(Status.FAILURE)  # stops the child if it runs
            yield self
            return
        yield from self.decorated.tick()
        status = self.decorated.status
        if status != Status.RUNNING:
            self.since = None
            self.stop(status)
        self.status = status
        yield self

    def update(self) -> Status:  # abstract in py_trees; tick above does the work
        return self.status

    def stop(self, new_status: Status) -> None:
        if new_status == Status.INVALID:
            self.since = None
        super().stop(new_status)

    def forget(self) -> None:
        self.since = None


class ThresholdParallel(Keeps, py_trees.composites.Composite):
    """btcap's Parallel rule: BehaviorTree.CPP's ParallelNode v4 thresholds, failure
    winning a tie; finished children kept across a halt; the children it halted are
    reset when it starts over."""

    def __init__(self, name: str, children: list[Any], need: int, fail: int | None) -> None:
        super().__init__(name, children)
        n = len(children)
        self.need = need if need >= 0 else n + 1 + need
        lost = n - self.need + 1
        self.fail_at = lost if fail is None else min(fail if fail >= 0 else n + 1 + fail, lost)
        self.pending: list[Any] | None = None
        self.ok = self.bad = 0
        self.halted: list[Any] = []

    def tick(self) -> Iterator[py_trees.behaviour.Behaviour]:
        if self.pending is None:
            for c in self.halted:
                forget(c)
            self.halted = []
            self.pending, self.ok, self.bad = list(self.children), 0, 0
        running = []
        for c in self.pending:
            yield from c.tick()
            if c.status == Status.SUCCESS:
                self.ok += 1
            elif c.status == Status.FAILURE:
                self.bad += 1
            else:
                running.append(c)
        if self.bad >= self.fail_at or self.ok >= self.need:
            for c in running:
                c.stop(Status.INVALID)
            self.halted, self.pending = running, None
            self.status = Status.FAILURE if self.bad >= self.fail_at else Status.SUCCESS
        else:
            self.pending, self.status = running, Status.RUNNING
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        for c in self.children:
            if c.status == Status.RUNNING:
                c.stop(Status.INVALID)
        self.status = new_status

    def forget(self) -> None:
        self.pending, self.halted = None, []


def build_py_trees(spec: Spec, log: Log, clock: TickClock) -> py_trees.behaviour.Behaviour:
    if spec.kind == "leaf":
        return PtLeaf(spec.name, spec.script, log, clock)
    kids = [build_py_trees(c, log, clock) for c in spec.children]
    k, name = spec.kind, spec.name
    d = py_trees.decorators
    if k == "rseq":
        return py_trees.composites.Sequence(name, memory=False, children=kids)
    if k == "rfb":
        return py_trees.composites.Selector(name, memory=False, children=kids)
    if k == "seq":
        return KeepSequence(name, memory=True, children=kids)
    if k == "fb":
        return KeepSelector(name, memory=True, children=kids)
    if k == "swm":
        return ResumeFailedSequence(name, memory=True, children=kids)
    if k == "par":
        return ThresholdParallel(name, kids, spec.need, spec.fail)
    if k == "retry":
        return KeepRetry(name, kids[0], num_failures=spec.arg + 1)
    if k == "repeat":
        return KeepRepeat(name, kids[0], num_success=spec.arg)
    if k == "timeout":
        return BtcapTimeout(name, kids[0], spec.arg, clock)
    remaps = {
        "inv": d.Inverter,
        "force_s": d.FailureIsSuccess,
        "force_f": d.SuccessIsFailure,
        "run_s": d.RunningIsSuccess,
        "run_f": d.RunningIsFailure,
    }
    return remaps[k](name=name, child=kids[0])
