"""Seeded random *mixed* trees for the tick benchmark, built alike in btcap and py_trees.

The generator, stated (:func:`mixed_spec`): trees of about :data:`TREE_NODES` nodes
(800-1200; the seed is stepped until one falls in that range), at most
:data:`DEPTH` levels and 2-:data:`FANOUT` children a composite. Below the root a node is
a leaf with probability ``0.08 * level``, else a decorator (30 %: Inverter,
ForceSuccess/Failure, RunningIsSuccess, Retry or Repeat with 1-3) or a composite drawn
evenly from Sequence and Fallback of both kinds (reactive, and with memory: they resume
at the running child) and, in the ``parallel`` variant, Parallel with random thresholds
(success 1..n, failure 1..n). Leaves do a little work on every tick (a multiply-add on
their own counter) and return the entry of their script for the current step, shared by
all leaves, so both libraries see the same inputs: at each step a leaf is running
(10 %), failed (30 %) or succeeded.

Mappings to py_trees: ``Sequence``/``Fallback`` (they resume at the running child) are
``Sequence``/``Selector`` with ``memory=True``, ``ReactiveSequence``/``ReactiveFallback``
the same with ``memory=False``; ``Retry(retries=k)`` is ``Retry(num_failures=k + 1)``;
ForceSuccess/ForceFailure are FailureIsSuccess/SuccessIsFailure. py_trees' Parallel has
no k-of-n thresholds (any failure fails it): a Parallel that needs every child is
``SuccessOnAll(synchronise=True)``, any other ``SuccessOnOne()``. The trees therefore
tick differently where thresholds differ, which is why the benchmark divides each
library's time by the nodes it ticked itself.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import py_trees

import btcap
from btcap.bt.invariants import check_halting, record_ticks

__all__ = [
    "STEPS",
    "MixedRun",
    "MixedSpec",
    "PtScripted",
    "Scripted",
    "Stepper",
    "btcap_run",
    "build_btcap",
    "build_py_trees",
    "mixed_spec",
    "py_trees_run",
]

#: Length of every leaf script; the shared step runs 0, 1, ..., STEPS - 1, 0, ...
STEPS = 16
#: Size, height and branching of the generated trees.
TREE_NODES, DEPTH, FANOUT = 1000, 6, 6
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
_PARALLELS = ("parallel",)


@dataclass(frozen=True, slots=True)
class MixedSpec:
    """One node: a composite/decorator kind with children, or a ``leaf`` with a script."""

    kind: str
    name: str
    arg: int = 0  # retries or repeat count; a Parallel's success threshold
    arg2: int = 0  # a Parallel's failure threshold
    script: str = ""  # leaf results per step, one of S/F/R each
    children: tuple[MixedSpec, ...] = ()

    def walk(self) -> Iterator[MixedSpec]:
        yield self
        for c in self.children:
            yield from c.walk()


def _script(rng: random.Random) -> str:
    """A leaf's results per step: running 10 %, failed 30 %, else succeeded."""
    return "".join(rng.choices((_R, _F, _S), (0.1, 0.3, 0.6), k=STEPS))


def mixed_spec(seed: int, *, parallel: bool, size: int = TREE_NODES) -> MixedSpec:
    """A random tree of ``size`` nodes, give or take 20 % (see the module's docstring)."""
    while True:
        spec = _random_tree(seed, parallel)
        if 0.8 * size <= sum(1 for _ in spec.walk()) <= 1.2 * size:
            return spec
        seed += 10_007


def _random_tree(seed: int, parallel: bool) -> MixedSpec:
    rng = random.Random(seed)
    counter = iter(range(1_000_000))
    kinds = _COMPOSITES + _PARALLELS if parallel else _COMPOSITES

    def node(level: int) -> MixedSpec:
        name = f"n{next(counter)}"
        if level == DEPTH or (level > 0 and rng.random() < 0.08 * level):
            return MixedSpec("leaf", name, script=_script(rng))
        if level > 0 and rng.random() < 0.3:
            kind = rng.choice(_DECORATORS)
            return MixedSpec(kind, name, arg=rng.randint(1, 3), children=(node(level + 1),))
        kind = rng.choice(kinds)
        kids = tuple(node(level + 1) for _ in range(rng.randint(2, FANOUT)))
        if kind == "parallel":
            n = len(kids)
            ok, bad = rng.randint(1, n), rng.randint(1, n)
            return MixedSpec(kind, name, arg=ok, arg2=bad, children=kids)
        return MixedSpec(kind, name, children=kids)

    return node(0)


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


def _interned(
    table: Mapping[str, object], script: str, cache: dict[str, tuple[object, ...]]
) -> Any:
    """The script as a tuple of results, one tuple per distinct script (in both libraries)."""
    found = cache.get(script)
    if found is None:
        found = cache[script] = tuple(table[c] for c in script)
    return found


class Scripted(btcap.Leaf):
    """Does a little work, then returns its script's entry for the shared step."""

    __slots__ = ("script", "step", "work")
    _scripts: ClassVar[dict[str, tuple[object, ...]]] = {}

    def __init__(self, name: str, script: str, step: Stepper) -> None:
        super().__init__(name)
        self.script: tuple[btcap.State, ...] = _interned(_STATE, script, self._scripts)
        self.step = step
        self.work = 0

    def on_tick(self) -> btcap.State:
        now = self.step.now
        self.work = (self.work * 31 + now) % 1_000_003
        return self.script[now]


class PtScripted(py_trees.behaviour.Behaviour):
    """The same leaf for py_trees."""

    _scripts: ClassVar[dict[str, tuple[object, ...]]] = {}

    def __init__(self, name: str, script: str, step: Stepper) -> None:
        super().__init__(name)
        self.script: tuple[py_trees.common.Status, ...] = _interned(_STATUS, script, self._scripts)
        self.step = step
        self.work = 0

    def update(self) -> py_trees.common.Status:
        now = self.step.now
        self.work = (self.work * 31 + now) % 1_000_003
        return self.script[now]


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
    if k == "parallel":
        ok, bad = spec.arg, spec.arg2
        return btcap.Parallel(spec.name, children=kids, success_threshold=ok, failure_threshold=bad)
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
    if k == "parallel":
        every = spec.arg == len(kids)
        chosen = policy.SuccessOnAll(synchronise=True) if every else policy.SuccessOnOne()
        return c.Parallel(name, chosen, children=kids)
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
