"""The tick benchmark's tree shapes, described once and built in each library, and the
check that every node was ticked on every tick with the result its shape promises, so a
faster figure can never come from doing less."""

from __future__ import annotations

import itertools
import sys
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from types import FrameType
from typing import Any

import py_trees

import btcap

__all__ = [
    "FLAT_LEAVES",
    "Spec",
    "balanced_spec",
    "btcap_tree",
    "build_btcap",
    "build_py_trees",
    "flat_spec",
    "node_count",
    "py_trees_root",
    "verify_btcap",
    "verify_py_trees",
]

FLAT_LEAVES = 1000
BALANCED_FANOUT = (5, 5, 6, 6)
VERIFY_TICKS = 3
SEQUENCE, FALLBACK, SUCCESS, FAILURE = "sequence", "fallback", "success", "failure"


# -- the shapes, library-neutral ---------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Spec:
    """One node: ``kind`` is a composite (sequence, fallback) or a leaf result.

    ``expect`` is the result the node must give on every tick (success or failure).
    """

    kind: str
    name: str
    expect: str
    children: tuple[Spec, ...] = ()

    def walk(self) -> Iterator[Spec]:
        yield self
        for c in self.children:
            yield from c.walk()


def flat_spec(leaves: int) -> Spec:
    """A Sequence of ``leaves`` successful leaves."""
    kids = tuple(Spec(SUCCESS, f"leaf{i}", SUCCESS) for i in range(leaves))
    return Spec(SEQUENCE, "root", SUCCESS, kids)


def balanced_spec(fanout: Sequence[int] = BALANCED_FANOUT) -> Spec:
    """Sequence at even depths, Fallback at odd ones; every node ticked; root succeeds."""
    names = itertools.count()

    def build(depth: int, expect: str) -> Spec:
        name = f"n{next(names)}"
        if depth == len(fanout):
            return Spec(expect, name, expect)
        kind = SEQUENCE if depth % 2 == 0 else FALLBACK
        go_on = SUCCESS if kind == SEQUENCE else FAILURE  # what lets the parent tick on
        k = fanout[depth]
        kids = tuple(build(depth + 1, expect if i == k - 1 else go_on) for i in range(k))
        return Spec(kind, name, expect, kids)

    return build(0, SUCCESS)


def node_count(spec: Spec) -> int:
    return sum(1 for _ in spec.walk())


# -- building -------------------------------------------------------------------------


def build_btcap(spec: Spec) -> btcap.Node:
    if spec.kind == SUCCESS:
        return btcap.AlwaysSuccess(spec.name)
    if spec.kind == FAILURE:
        return btcap.AlwaysFailure(spec.name)
    kids = [build_btcap(c) for c in spec.children]
    cls = btcap.ReactiveSequence if spec.kind == SEQUENCE else btcap.ReactiveFallback
    return cls(spec.name, children=kids)


def build_py_trees(spec: Spec) -> py_trees.behaviour.Behaviour:
    if spec.kind == SUCCESS:
        return py_trees.behaviours.Success(spec.name)
    if spec.kind == FAILURE:
        return py_trees.behaviours.Failure(spec.name)
    kids = [build_py_trees(c) for c in spec.children]
    cls = py_trees.composites.Sequence if spec.kind == SEQUENCE else py_trees.composites.Selector
    return cls(spec.name, memory=False, children=kids)


def btcap_tree(spec: Spec) -> btcap.Tree:
    tree = btcap.Tree(build_btcap(spec))
    tree.setup()
    return tree


def py_trees_root(spec: Spec) -> py_trees.behaviour.Behaviour:
    root = build_py_trees(spec)
    py_trees.trees.setup(root)
    return root


# -- verification: every node ticked on every tick, with the expected result ---------------

_BTCAP_STATE = {SUCCESS: btcap.State.SUCCEEDED, FAILURE: btcap.State.FAILED}
_PY_TREES_STATUS = {
    SUCCESS: py_trees.common.Status.SUCCESS,
    FAILURE: py_trees.common.Status.FAILURE,
}


def verify_btcap(spec: Spec, tree: btcap.Tree, ticks: int = VERIFY_TICKS) -> None:
    counts: Counter[int] = Counter()
    nodes = list(tree.nodes())
    codes = {type(n).tick.__code__ for n in nodes}  # whichever tick each class runs

    def hook(frame: FrameType, event: str, arg: Any) -> None:
        if event == "call" and frame.f_code in codes:
            counts[id(frame.f_locals["self"])] += 1

    sys.setprofile(hook)
    try:
        results = [tree.tick() for _ in range(ticks)]
    finally:
        sys.setprofile(None)
    assert results == [_BTCAP_STATE[spec.expect]] * ticks, f"btcap root gave {results}"
    assert len(nodes) == node_count(spec), (len(nodes), node_count(spec))
    assert len(counts) == len(nodes), f"btcap ticked {len(counts)} of {len(nodes)} nodes"
    for s, n in zip(spec.walk(), nodes, strict=True):
        assert n.name == s.name, (n.name, s.name)
        assert counts[id(n)] == ticks, f"btcap {n.path}: ticked {counts[id(n)]}x in {ticks} ticks"
        assert n.state is _BTCAP_STATE[s.expect], f"btcap {n.path}: {n.state}, not {s.expect}"


def verify_py_trees(
    spec: Spec, root: py_trees.behaviour.Behaviour, ticks: int = VERIFY_TICKS
) -> None:
    counts: Counter[Any] = Counter()
    for _ in range(ticks):
        for b in root.tick():
            counts[b.id] += 1
    expected = _PY_TREES_STATUS[spec.expect]
    assert root.status == expected, f"py_trees root gave {root.status}"
    nodes = list(_pre_order(root))
    assert len(nodes) == node_count(spec), (len(nodes), node_count(spec))
    assert len(counts) == len(nodes), f"py_trees ticked {len(counts)} of {len(nodes)} nodes"
    for s, b in zip(spec.walk(), nodes, strict=True):
        assert b.name == s.name, (b.name, s.name)
        assert counts[b.id] == ticks, f"py_trees {b.name}: ticked {counts[b.id]}x in {ticks} ticks"
        assert b.status == _PY_TREES_STATUS[s.expect], f"py_trees {b.name}: {b.status}"


def _pre_order(b: py_trees.behaviour.Behaviour) -> Iterator[py_trees.behaviour.Behaviour]:
    yield b
    for c in b.children:
        yield from _pre_order(c)
