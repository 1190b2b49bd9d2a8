"""Seeded random *mixed* trees for the tick benchmark, built alike in btcap and py_trees.

A mixed tree has Sequences/Fallbacks of both kinds, decorators (Inverter,
ForceSuccess/Failure, RunningIsSuccess, Retry, Repeat) and, in the ``parallel`` variant,
Parallels, over scripted leaves that look like conditions (mostly succeed) and actions
(run for a few ticks, then succeed or fail). Every leaf returns the entry of its script for
the current step, shared by all leaves, so both libraries see the same inputs.

Mappings to py_trees: ``Sequence``/``Fallback`` (they resume at the running child) are
``Sequence``/``Selector`` with ``memory=True``, ``ReactiveSequence``/``ReactiveFallback``
the same with ``memory=False``; ``Parallel()`` (all must succeed) is
``SuccessOnAll(synchronise=True)`` and ``Parallel(success_threshold=1,
failure_threshold=1)`` is ``SuccessOnOne()``; ``Retry(retries=k)`` is
``Retry(num_failures=k + 1)``; ForceSuccess/ForceFailure are FailureIsSuccess/
SuccessIsFailure.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import py_trees

import btcap
from btcap.bt.invariants import check_halting, record_ticks

__all__ = [
    "STEPS",
    "MixedRun",
    "MixedSpec",
    "Stepper",
    "btcap_run",
    "build_btcap",
    "build_py_trees",
    "mixed_spec",
    "py_trees_run",
]

#: Length of every leaf script; the shared step runs 0, 1, ..., STEPS - 1, 0, ...
STEPS = 16
_S, _F, _R = "S", "F", "R"
#: In this order, so the seeded trees stay the ones measured before the 0.2 renaming.
_COMPOSITES = ("reactive_sequence", "reactive_fallback", "sequence", "fallback")
_DECORATORS = (
    "inverter",
    "force_success",
    "force_failure",
    "running_is_success",
    "retry",
    "repeat",
)
_PARALLELS = ("parallel_all", "parallel_one")


@dataclass(frozen=True, slots=True)
class MixedSpec:
    """One node: a composite/decorator kind with children, or a ``leaf`` with a script."""

    kind: str
    name: str
    arg: int = 0  # retries or repeat count
    script: str = ""  # leaf results per step, one of S/F/R each
    children: tuple[MixedSpec, ...] = ()

    def walk(self) -> Iterator[MixedSpec]:
        yield self
        for c in self.children:
            yield from c.walk()


def _script(rng: random.Random) -> str:
    if rng.random() < 0.4:  # a condition: holds most of the time
        return "".join(_F if rng.random() < 0.15 else _S for _ in range(STEPS))
    out: list[str] = []  # an action: runs a few ticks, then succeeds (mostly) or fails
    while len(out) < STEPS:
        out += [_R] * rng.randint(1, 4) + [_F if rng.random() < 0.2 else _S]
    return "".join(out[:STEPS])


def mixed_spec(seed: int, *, parallel: bool, depth: int = 5, fanout: int = 4) -> MixedSpec:
    """A random tree of height at most ``depth`` and at most ``fanout`` children a node."""
    rng = random.Random(seed)
    counter = iter(range(1_000_000))
    kinds = _COMPOSITES + _PARALLELS if parallel else _COMPOSITES

    def node(level: int) -> MixedSpec:
        name = f"n{next(counter)}"
        if level == depth or rng.random() < 0.1 * (level - 1):
            return MixedSpec("leaf", name, script=_script(rng))
        if rng.random() < 0.3:
            kind = rng.choice(_DECORATORS)
            return MixedSpec(kind, name, arg=rng.randint(1, 3), children=(node(level + 1),))
        kind = rng.choice(kinds)
        kids = tuple(node(level + 1) for _ in range(rng.randint(2, fanout)))
        return MixedSpec(kind, name, children=kids)

    root = node(0)
    if root.kind == "leaf":
        return mixed_spec(seed + 10_007, parallel=parallel, depth=depth, fanout=fanout)
    return root


class Stepper:
    """The shared step every scripted leaf reads."""

    __slots__ = ("now",)

    def __init__(self) -> None:
        self.now = 0

    def advance(self) -> None:
        self.now = (self.now + 1) % STEPS


_STATE = {_S: btcap.State.SUCCEEDED, _F: btcap.State.FAILED, _R: btcap.State.RUNNING}
_STATUS = {
    _S: py_trees.common.Status.SUCCESS,
    _F: py_trees.common.Status.FAILURE,
    _R: py_trees.common.Status.RUNNING,
}


class Scripted(btcap.Leaf):
    """Returns its script's entry for the shared step."""

    __slots__ = ("script", "step")

    def __init__(self, name: str, script: str, step: Stepper) -> None:
        super().__init__(name)
        self.script = tuple(_STATE[c] for c in script)
        self.step = step

    def on_tick(self) -> btcap.State:
        return self.script[self.step.now]


class PtScripted(py_trees.behaviour.Behaviour):
    """The same leaf for py_trees."""

    def __init__(self, name: str, script: str, step: Stepper) -> None:
        super().__init__(name)
        self.script = tuple(_STATUS[c] for c in script)
        self.step = step

    def update(self) -> py_trees.common.Status:
        return self.script[self.step.now]


_BTCAP_DECORATORS: dict[str, type[btcap.Node]] = {
    "inverter": btcap.Inverter,
    "force_success": btcap.ForceSuccess,
    "force_failure": btcap.ForceFailure,
    "running_is_success": btcap.RunningIsSuccess,
}


def build_btcap(spec: MixedSpec, step: Stepper) -> btcap.Node:
    if spec.kind == "leaf":
        return Scripted(spec.name, spec.script, step)
    kids = [build_btcap(c, step) for c in spec.children]
    k = spec.kind
    if k in _BTCAP_DECORATORS:
        return _BTCAP_DECORATORS[k](spec.name, children=kids)
    if k == "retry":
        return btcap.Retry(spec.name, children=kids, retries=spec.arg)
    if k == "repeat":
        return btcap.Repeat(spec.name, children=kids, times=spec.arg)
    if k == "parallel_all":
        return btcap.Parallel(spec.name, children=kids)
    if k == "parallel_one":
        return btcap.Parallel(spec.name, children=kids, success_threshold=1, failure_threshold=1)
    cls = {
        "reactive_sequence": btcap.ReactiveSequence,
        "reactive_fallback": btcap.ReactiveFallback,
        "sequence": btcap.Sequence,
        "fallback": btcap.Fallback,
    }[k]
    return cls(spec.name, children=kids)


def build_py_trees(spec: MixedSpec, step: Stepper) -> py_trees.behaviour.Behaviour:
    if spec.kind == "leaf":
        return PtScripted(spec.name, spec.script, step)
    kids = [build_py_trees(c, step) for c in spec.children]
    k, name = spec.kind, spec.name
    d = py_trees.decorators
    if k == "inverter":
        return d.Inverter(name, kids[0])
    if k == "force_success":
        return d.FailureIsSuccess(name, kids[0])
    if k == "force_failure":
        return d.SuccessIsFailure(name, kids[0])
    if k == "running_is_success":
        return d.RunningIsSuccess(name, kids[0])
    if k == "retry":
        return d.Retry(name, kids[0], num_failures=spec.arg + 1)
    if k == "repeat":
        return d.Repeat(name, kids[0], num_success=spec.arg)
    policy = py_trees.common.ParallelPolicy
    c = py_trees.composites
    if k == "parallel_all":
        return c.Parallel(name, policy.SuccessOnAll(synchronise=True), children=kids)
    if k == "parallel_one":
        return c.Parallel(name, policy.SuccessOnOne(), children=kids)
    memory = not k.startswith("reactive_")
    cls = c.Sequence if k.endswith("sequence") else c.Selector
    return cls(name, memory=memory, children=kids)


class MixedRun:
    """One library's trees of a mixed shape: :meth:`reset` (untimed) then :meth:`run`."""

    def __init__(
        self,
        ticks: list[Callable[[], object]],
        reset: Callable[[], None],
        step: Stepper,
        count: Callable[[], int],
    ) -> None:
        self.ticks = ticks
        self._reset = reset
        self.step = step
        self._count = count

    def reset(self) -> None:
        self._reset()
        self.step.now = 0

    def run(self) -> None:
        """Tick every tree once per step, for ``STEPS`` steps."""
        ticks, step = self.ticks, self.step
        for _ in range(STEPS):
            for tick in ticks:
                tick()
            step.advance()

    def ticked(self) -> int:
        """Nodes ticked in one run from reset (the run itself is not timed)."""
        self.reset()
        return self._count()


def btcap_run(specs: list[MixedSpec]) -> MixedRun:
    """The trees in btcap; counting also checks the halting invariant after every tick."""
    step = Stepper()
    trees = [btcap.Tree(build_btcap(s, step), name=s.name) for s in specs]
    for t in trees:
        t.setup()

    def reset() -> None:
        for t in trees:
            t.reset()

    def count() -> int:
        n = 0
        for _ in range(STEPS):
            for t in trees:
                _, ticked = record_ticks(t, t.tick)
                check_halting(t, ticked)
                n += len(ticked)
            step.advance()
        return n

    return MixedRun([t.tick for t in trees], reset, step, count)


def py_trees_run(specs: list[MixedSpec]) -> MixedRun:
    step = Stepper()
    roots = [build_py_trees(s, step) for s in specs]
    for r in roots:
        py_trees.trees.setup(r)

    def reset() -> None:
        for r in roots:
            r.stop(py_trees.common.Status.INVALID)

    def count() -> int:
        n = 0
        for _ in range(STEPS):
            for r in roots:
                n += sum(1 for _ in r.tick())  # every node yields itself once per tick
            step.advance()
        return n

    return MixedRun([r.tick_once for r in roots], reset, step, count)
