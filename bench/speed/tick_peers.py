"""The tick benchmark's other measurements, each against its peer in the same run.

- BehaviorTree.CPP 4.8 through ``behaviortreepy`` (if installed), ticking the ``flat`` and
  ``balanced`` shapes with its own C++ ``AlwaysSuccess``/``AlwaysFailure`` leaves and
  reactive composites, taking turns with btcap and py_trees.
- The two ways of writing a leaf: ``return State.SUCCEEDED`` (as the docs show) against
  ``return SUCCEEDED`` (a module constant), each in a flat ReactiveSequence of 1000.
- Memory per node at :data:`MEMORY_NODES` nodes (``tracemalloc``, traced bytes held after
  building and setting up), btcap against py_trees: a flat Sequence, and the mixed
  trees with Parallel (:mod:`.mixed_trees`) under one reactive Sequence until there are
  that many nodes. Node names and leaf scripts exist before tracing starts, so neither
  library is charged for them.
"""

from __future__ import annotations

import gc
import os
import tracemalloc
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import py_trees

import btcap
from btcap import State
from btcap.bench.speed.mixed_trees import MixedSpec, PtScripted, Scripted, Stepper, mixed_spec
from btcap.bench.speed.mixed_trees import build_btcap as build_mixed_btcap
from btcap.bench.speed.mixed_trees import build_py_trees as build_mixed_py_trees

__all__ = [
    "MEMORY_NODES",
    "btcpp_tick",
    "leaf_form_trees",
    "load_average",
    "markdown",
    "memory",
]

MEMORY_NODES = 100_000
LEAF_FORM_LEAVES = 1000
_SUCCEEDED = State.SUCCEEDED


def load_average() -> float:
    """The 1-minute load average (what else the shared machine was doing)."""
    return round(os.getloadavg()[0], 2)


# -- BehaviorTree.CPP ---------------------------------------------------------------------


def btcpp_tick(spec: Any) -> Callable[[], object] | None:
    """A tick of ``spec`` (a :class:`~btcap.bench.speed.shapes.Spec`) in
    BehaviorTree.CPP, checked to give the expected result; None without ``behaviortreepy``."""
    try:
        import behaviortreepy as bt  # type: ignore[import-untyped,import-not-found,unused-ignore]
    except ImportError:
        return None
    tags = {
        "sequence": "ReactiveSequence",
        "fallback": "ReactiveFallback",
        "success": "AlwaysSuccess",
        "failure": "AlwaysFailure",
    }

    def xml(s: Any) -> str:
        inner = "".join(xml(c) for c in s.children)
        return f'<{tags[s.kind]} name="{s.name}">{inner}</{tags[s.kind]}>'

    text = f'<root BTCPP_format="4"><BehaviorTree ID="main">{xml(spec)}</BehaviorTree></root>'
    tree = bt.BehaviorTreeFactory().create_tree_from_text(text)
    expected = bt.NodeStatus.SUCCESS if spec.expect == "success" else bt.NodeStatus.FAILURE
    got = tree.tick_exactly_once()
    assert got == expected, f"BehaviorTree.CPP root gave {got}"
    tick: Callable[[], object] = tree.tick_exactly_once
    return tick


# -- the two ways of writing a leaf ---------------------------------------------------------


class EnumLeaf(btcap.Leaf):
    """A leaf as the docs write one."""

    __slots__ = ()

    def on_tick(self) -> State:
        return State.SUCCEEDED


class ConstantLeaf(btcap.Leaf):
    """The same leaf returning a module constant."""

    __slots__ = ()

    def on_tick(self) -> btcap.State:
        return _SUCCEEDED


def leaf_form_trees() -> dict[str, btcap.Tree]:
    """A flat ReactiveSequence of 1000 leaves of each form, set up."""
    out = {}
    for form, cls in (("State.SUCCEEDED", EnumLeaf), ("module constant", ConstantLeaf)):
        kids = [cls(f"l{i}") for i in range(LEAF_FORM_LEAVES)]
        tree = btcap.Tree(btcap.ReactiveSequence("root", children=kids))
        tree.setup()
        assert tree.tick() is _SUCCEEDED
        out[form] = tree
    return out


# -- memory ------------------------------------------------------------------------------------


def _traced(build: Callable[[], object]) -> int:
    """Traced bytes still held after ``build()``."""
    gc.collect()
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        keep = build()
        gc.collect()
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    del keep
    return after - before


def _mixed_forest(nodes: int) -> MixedSpec:
    """Mixed trees with Parallel under one ReactiveSequence, ``nodes`` nodes or a few more."""
    kids: list[MixedSpec] = []
    total, seed = 1, 1
    while total < nodes:
        kids.append(replace(mixed_spec(seed, parallel=True), name=f"tree{seed}"))
        total += sum(1 for _ in kids[-1].walk())
        seed += 1
    return MixedSpec("reactive_sequence", "forest", children=tuple(kids))


def memory(flat: Any, build_btcap: Any, build_py_trees: Any) -> dict[str, Any]:
    """Bytes per node, btcap and py_trees, for a flat Sequence of :data:`MEMORY_NODES` and
    mixed trees of as many nodes (``flat`` is the flat Spec, with its two builders)."""
    forest = _mixed_forest(MEMORY_NODES)
    mixed_nodes = sum(1 for _ in forest.walk())
    step = Stepper()
    for s in forest.walk():  # the scripts, like the names, exist before tracing
        if s.kind == "leaf":
            Scripted("warm", s.script, step)
            PtScripted("warm", s.script, step)

    def btcap_tree(root: Callable[[], btcap.Node]) -> Callable[[], object]:
        def build() -> object:
            tree = btcap.Tree(root())
            tree.setup()
            return tree

        return build

    def py_trees_tree(root: Callable[[], py_trees.behaviour.Behaviour]) -> Callable[[], object]:
        def build() -> object:
            tree = py_trees.trees.BehaviourTree(root())
            tree.setup()
            return tree

        return build

    shapes = {
        "flat": (
            MEMORY_NODES,
            btcap_tree(lambda: build_btcap(flat)),
            py_trees_tree(lambda: build_py_trees(flat)),
        ),
        "mixed": (
            mixed_nodes,
            btcap_tree(lambda: build_mixed_btcap(forest, step)),
            py_trees_tree(lambda: build_mixed_py_trees(forest, step)),
        ),
    }
    out: dict[str, Any] = {"nodes": {}, "btcap": {}, "py_trees": {}, "ratio": {}}
    for shape, (n, b, p) in shapes.items():
        out["nodes"][shape] = n
        out["btcap"][shape] = _traced(b) / n
        out["py_trees"][shape] = _traced(p) / n
        out["ratio"][shape] = out["btcap"][shape] / out["py_trees"][shape]
    return out


# -- the README's rows -----------------------------------------------------------------------


def markdown(data: dict[str, Any]) -> str:
    """The README performance table's tick and memory rows, from :func:`.tick.run`'s data."""
    us = {lib: {k: 1000 * v for k, v in d.items()} for lib, d in data["cpu_us_per_node"].items()}
    ratio, bt, mem = data["cpu_speedup"], data["btcpp_cpu_ns_per_node"], data["memory"]
    forms = {k: 1000 * v for k, v in data["leaf_forms_cpu_us_per_node"].items()}
    x = "\u00d7"
    flat_peer = f"py_trees {us['py_trees']['flat'] / 1000:.2f} µs/node ({ratio['flat']:.0f}{x})"
    if "flat" in bt:
        flat_peer += f"; BehaviorTree.CPP {bt['flat']:.0f} ns/node"
    m, p = "mixed", "mixed_parallel"
    rows = [
        f"<!-- python -m btcap.bench tick, load average {data['load_average']['start']} -->",
        f"| tick, flat `ReactiveSequence` of 1000 leaves | {us['btcap']['flat']:.0f} ns/node "
        f"| {flat_peer} |",
        "| tick, random mixed trees of ~1000 nodes / with Parallels (per ticked node) "
        f"| {us['btcap'][m]:.0f} / {us['btcap'][p]:.0f} ns/node "
        f"| py_trees {us['py_trees'][m] / 1000:.2f} / {us['py_trees'][p] / 1000:.2f} µs/node "
        f"({ratio[m]:.0f}{x} / {ratio[p]:.0f}{x}) |",
        f"| leaf written `return State.SUCCEEDED` | {forms['State.SUCCEEDED']:.0f} ns/node "
        f"| `return SUCCEEDED` (`from btcap import SUCCEEDED`, as the docs show): "
        f"{forms['module constant']:.0f} ns/node |",
        f"| memory, flat / mixed trees of 100,000 nodes | {mem['btcap']['flat']:.0f} / "
        f"{mem['btcap']['mixed']:.0f} B/node | py_trees {mem['py_trees']['flat']:.0f} / "
        f"{mem['py_trees']['mixed']:.0f} B/node ({mem['ratio']['flat']:.2f}{x} / "
        f"{mem['ratio']['mixed']:.2f}{x}) |",
    ]
    return "\n".join(rows)
