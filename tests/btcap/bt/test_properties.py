"""Property tests: random trees against a small reference evaluator, plus tick invariants.

The reference evaluates a tree spec tick by tick. It is pure for the reactive composites;
Sequence, Fallback, SequenceWithMemory and Parallel keep a little state in a dict keyed by
path, exactly as much as the semantics require (which child a composite resumes at,
which Parallel children are done or were halted). It also reports which nodes a tick
visits and what each returned.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import hypothesis.strategies as st
import pytest
from hypothesis import HealthCheck, given, settings

from btcap import (
    AlwaysFailure,
    AlwaysRunning,
    AlwaysSuccess,
    Fallback,
    ForceFailure,
    ForceSuccess,
    Inverter,
    Leaf,
    Node,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Sequence,
    SequenceWithMemory,
    State,
    Tree,
    protocol_registry,
)
from btcap.bt.messages import NodeStatus, Tick
from btcap.bt.state import ACTIVE
from btcap.transports import Codec, Message

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING

# Random trees include reactive composites that restart a child over and over: btcap
# warns about that (a diagnostic for whoever wrote the tree), which the suite's
# "warnings are errors" would turn into a failure of the semantics compared here.
pytestmark = pytest.mark.filterwarnings("ignore::btcap.bt.state.RestartLoopWarning")

PROPS = settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)

# -- specs --------------------------------------------------------------------------------


@dataclass(frozen=True)
class LeafSpec:
    """A leaf whose result at global tick ``t`` is ``script[t % len(script)]``."""

    script: tuple[State, ...]


@dataclass(frozen=True)
class NodeSpec:
    kind: str
    children: tuple[Spec, ...]


Spec = LeafSpec | NodeSpec

COMPOSITES = ("rseq", "rfb", "seq", "fb", "swm")
#: A Parallel's child that was still running when it decided: reset when it starts over.
HALTED = "halted"
DECORATORS = ("inv", "force_success", "force_failure")


def trees(
    leaf: st.SearchStrategy[LeafSpec], composites: tuple[str, ...] = COMPOSITES
) -> st.SearchStrategy[Spec]:
    def extend(kids: st.SearchStrategy[Spec]) -> st.SearchStrategy[Spec]:
        return st.one_of(
            st.builds(
                NodeSpec,
                st.sampled_from(composites),
                st.lists(kids, max_size=4).map(tuple),
            ),
            st.builds(NodeSpec, st.sampled_from(DECORATORS), kids.map(lambda c: (c,))),
        )

    return st.recursive(leaf, extend, max_leaves=10)


def fixed(*results: State) -> st.SearchStrategy[LeafSpec]:
    return st.sampled_from(results).map(lambda r: LeafSpec((r,)))


SCRIPTED = st.lists(st.sampled_from([S, F, R]), min_size=1, max_size=4).map(
    lambda s: LeafSpec(tuple(s))
)

# -- the reference ------------------------------------------------------------------------


@dataclass
class Ref:
    """Reference state: memory per path, and what the current tick visited."""

    memory: dict[str, Any] = field(default_factory=dict)
    visited: dict[str, State] = field(default_factory=dict)
    halted: set[str] = field(default_factory=set)

    def tick(self, spec: Spec, t: int) -> State:
        self.visited = {}
        self.halted = set()
        return self._eval(spec, "r", t)

    def reset(self, under: str = "") -> None:
        for key in [k for k in self.memory if k.startswith(under)]:
            del self.memory[key]

    def _eval(self, spec: Spec, path: str, t: int) -> State:
        result = self._result(spec, path, t)
        self.visited[path] = result
        return result

    def _result(self, spec: Spec, path: str, t: int) -> State:
        if isinstance(spec, LeafSpec):
            return spec.script[t % len(spec.script)]
        kids = [(c, f"{path}/n{i}") for i, c in enumerate(spec.children)]
        kind = spec.kind
        if kind in DECORATORS:
            r = self._eval(kids[0][0], kids[0][1], t)
            remap = {
                "inv": {S: F, F: S},
                "force_success": {F: S},
                "force_failure": {S: F},
            }[kind]
            return remap.get(r, r)
        if kind in ("rseq", "rfb"):  # from the first child every tick
            go_on = S if kind == "rseq" else F
            for c, p in kids:
                r = self._eval(c, p, t)
                if r is not go_on:
                    return r
            return go_on
        if kind in ("seq", "fb", "swm"):  # resume where they were
            go_on = F if kind == "fb" else S
            i = self.memory.get(path, 0)
            while i < len(kids):
                r = self._eval(kids[i][0], kids[i][1], t)
                if r is R:
                    self.memory[path] = i
                    return R
                if r is not go_on:
                    self.memory[path] = i if kind == "swm" else 0  # swm: at the failed child
                    return r
                i += 1
            self.memory[path] = 0
            return go_on
        assert kind == "par"  # default thresholds: all must succeed, any failure fails
        done: list[State | str | None] | None = self.memory.get(path)
        if done is None or all(d is not None for d in done):
            if done is not None:  # a finished Parallel restarts the children it halted
                for (_, p), d in zip(kids, done, strict=True):
                    if d == HALTED:
                        self.reset(p)
            done = [None] * len(kids)
        for i, (c, p) in enumerate(kids):
            if done[i] is None:
                r = self._eval(c, p, t)
                if r is not R:
                    done[i] = r
        ok, bad = done.count(S), done.count(F)
        if ok == len(kids) or bad >= 1:
            self.memory[path] = [HALTED if d is None else d for d in done]
            # What still runs below a finished Parallel is unticked in the same tick.
            below = path + "/"
            self.halted.update(p for p, r in self.visited.items() if p.startswith(below) and r is R)
            return S if ok == len(kids) else F
        self.memory[path] = done
        return R


def reference_once(spec: Spec) -> State:
    """The result of one tick of a fresh tree, as a pure function."""
    return Ref().tick(spec, 0)


# -- building real trees ------------------------------------------------------------------


@dataclass
class Ctx:
    t: int = 0
    ticked: set[str] = field(default_factory=set)


class Recording(Node):
    """Mixed into every node class below: notes the node's path when it is ticked."""

    ctx: Ctx

    def on_tick(self) -> State:
        self.ctx.ticked.add(self.path)
        return super().on_tick()


class Scripted(Leaf):
    ctx: Ctx

    def __init__(self, name: str, script: tuple[State, ...]) -> None:
        super().__init__(name)
        self.script = script

    def on_tick(self) -> State:
        self.ctx.ticked.add(self.path)
        return self.script[self.ctx.t % len(self.script)]


class RReactiveSequence(Recording, ReactiveSequence): ...


class RReactiveFallback(Recording, ReactiveFallback): ...


class RSequence(Recording, Sequence): ...


class RFallback(Recording, Fallback): ...


class RSequenceWithMemory(Recording, SequenceWithMemory): ...


class RInverter(Recording, Inverter): ...


class RForceSuccess(Recording, ForceSuccess): ...


class RForceFailure(Recording, ForceFailure): ...


class RParallel(Recording, Parallel): ...


KINDS: dict[str, type[Recording]] = {
    "rseq": RReactiveSequence,
    "rfb": RReactiveFallback,
    "seq": RSequence,
    "fb": RFallback,
    "swm": RSequenceWithMemory,
    "inv": RInverter,
    "force_success": RForceSuccess,
    "force_failure": RForceFailure,
    "par": RParallel,
}


def build(spec: Spec, name: str, ctx: Ctx) -> Node:
    node: Recording | Scripted
    if isinstance(spec, LeafSpec):
        node = Scripted(name, spec.script)
    else:
        kids = [build(c, f"n{i}", ctx) for i, c in enumerate(spec.children)]
        node = KINDS[spec.kind](name, children=kids)
    node.ctx = ctx
    return node


def build_plain(spec: Spec, name: str = "r") -> Node:
    """The same tree from the library's own classes and always-leaves (no recording)."""
    if isinstance(spec, LeafSpec):
        return {S: AlwaysSuccess, F: AlwaysFailure, R: AlwaysRunning}[spec.script[0]](name)
    plain: dict[str, type[Node]] = {
        "rseq": ReactiveSequence,
        "rfb": ReactiveFallback,
        "seq": Sequence,
        "fb": Fallback,
        "swm": SequenceWithMemory,
        "inv": Inverter,
        "force_success": ForceSuccess,
        "force_failure": ForceFailure,
        "par": Parallel,
    }
    kids = [build_plain(c, f"n{i}") for i, c in enumerate(spec.children)]
    return plain[spec.kind](name, children=kids)


def check_tick(tree: Tree, ctx: Ctx, ref: Ref, spec: Spec) -> None:
    """Tick both and compare everything observable; then check the invariants."""
    ctx.ticked = set()
    got = tree.tick()
    want = ref.tick(spec, ctx.t)
    assert got is want
    assert ctx.ticked == set(ref.visited), "a different set of nodes was ticked"
    states = {n.path: n.state for n in tree.nodes()}
    for path, result in ref.visited.items():
        expected = State.PAUSED if path in ref.halted else result
        assert states[path] is expected, f"{path} is {states[path]}, expected {expected}"
    for n in tree.nodes():
        if n.path in ctx.ticked:
            continue
        # Abandoned children are unticked: nothing left running without being ticked...
        assert n.state not in ACTIVE, f"{n.path} left {n.state.value} without a tick"
        # ... and in particular never below a parent that has finished.
        parent = n.parent_node
        if parent is not None and parent.state in (S, F):
            assert n.state is not R
    ctx.t += 1


# -- properties ---------------------------------------------------------------------------


@PROPS
@given(trees(fixed(S, F)))
def test_success_failure_trees_match_the_reference(spec: Spec) -> None:
    want = reference_once(spec)
    tree = Tree(build_plain(spec))
    for _ in range(3):
        assert tree.tick() is want
    ctx = Ctx()
    rtree, ref = Tree(build(spec, "r", ctx)), Ref()
    for _ in range(3):
        check_tick(rtree, ctx, ref, spec)


@PROPS
@given(trees(fixed(S, F, R)))
def test_trees_with_running_leaves_match_the_reference(spec: Spec) -> None:
    want = reference_once(spec)
    tree = Tree(build_plain(spec))
    for _ in range(3):
        assert tree.tick() is want  # static leaves: memory nodes resume to the same result
    ctx = Ctx()
    rtree, ref = Tree(build(spec, "r", ctx)), Ref()
    for _ in range(3):
        check_tick(rtree, ctx, ref, spec)


@PROPS
@given(
    trees(SCRIPTED, (*COMPOSITES, "par")),
    st.lists(st.sampled_from(["tick"] * 6 + ["untick", "reset"]), min_size=1, max_size=12),
)
def test_changing_leaves_match_the_reference_and_abandoned_children_are_unticked(
    spec: Spec, actions: list[str]
) -> None:
    ctx = Ctx()
    tree, ref = Tree(build(spec, "r", ctx)), Ref()
    for action in actions:
        if action == "tick":
            check_tick(tree, ctx, ref, spec)
        elif action == "untick":
            tree.untick()
            assert not [n for n in tree.nodes() if n.state in ACTIVE]
        else:
            tree.reset()
            ref.reset()
            assert {n.state for n in tree.nodes()} <= {State.IDLE, State.UNINITIALIZED}


# -- messages -----------------------------------------------------------------------------

scalars = (
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**63), max_value=2**64 - 1)
    | st.floats(allow_nan=False)
    | st.text(max_size=5)
)
values = st.one_of(
    scalars,
    st.lists(scalars, max_size=3),
    st.dictionaries(st.text(max_size=3), scalars, max_size=3),
)
port_values = st.dictionaries(st.sampled_from(["x", "pose", "goal_id", "ok", "v"]), values)


@PROPS
@given(
    st.one_of(
        st.builds(NodeStatus, st.sampled_from(list(State)), port_values),
        st.builds(Tick, port_values),
    )
)
def test_node_messages_survive_the_codec(msg: Message) -> None:
    codec = Codec(protocol_registry())
    assert codec.decode_message(codec.encode_message(msg)) == msg
