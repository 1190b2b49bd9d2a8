"""Script evaluation cost: btcap's Script node vs a Python leaf doing the same work, and
vs BehaviorTree.CPP 4.8's Script through ``behaviortreepy``, in one run.

The tree: a Sequence of 100 nodes, each doing ``a := b * 2 + c; b += 1; ok := a > c``
on entries of the tree's blackboard (``b`` and ``c`` doubles, created by a first
Script). Three forms of it, ticked in turns (:func:`btcap.bench.speed.tick.time_shape`):

- ``script``: btcap loading the BehaviorTree.CPP XML (its Script nodes compiled once
  to closures at load);
- ``python``: btcap with a Python leaf of the same work in place of each Script (the
  same blackboard dict, read and written by key);
- ``btcpp``: BehaviorTree.CPP loading the same XML, when ``behaviortreepy`` is installed.

Reported: microseconds per scripted node (median of per-tick time / 100), and the
ratios script / python and btcpp / script. All three are checked to compute the same
values first. ``python -m btcap.bench script [--quick]``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import btcap
from btcap.bench.common import percentiles, write_result
from btcap.bench.speed.tick import time_shape
from btcap.bench.speed.tick_peers import load_average
from btcap.bt.files import loads_tree
from btcap.bt.registry import default_registry

NODES = 100
CODE = "a := b * 2 + c; b += 1; ok := a > c"
_INIT = "b := 0.5; c := 3.0"


class PythonScript(btcap.Leaf):
    """The script's work written as a Python leaf over the same blackboard entries."""

    __slots__ = ("values",)
    values: dict[str, Any]

    def on_tick(self) -> btcap.State:
        v = self.values
        v["a"] = v["b"] * 2 + v["c"]
        v["b"] += 1.0
        v["ok"] = 1.0 if v["a"] > v["c"] else 0.0
        return btcap.SUCCEEDED


def _xml(leaf: str) -> str:
    body = "".join(leaf for _ in range(NODES))
    return (
        '<root BTCPP_format="4"><BehaviorTree ID="Main"><Sequence>'
        f'<Script code="{_INIT}"/>{body}</Sequence></BehaviorTree></root>'
    )


def _btcap(python: bool) -> btcap.Tree:
    reg = default_registry(plugins=False)
    reg.register(PythonScript)
    leaf = "<PythonScript/>" if python else f'<Script code="{CODE}"/>'
    tree = loads_tree(_xml(leaf), "xml", reg)
    board = tree.blackboard
    assert board is not None
    if python:
        board.declare("a", btcap.Port(float))
        board.declare("ok", btcap.Port(float))
        for node in tree.root.walk():
            if isinstance(node, PythonScript):
                node.values = board.outputs
    return tree


def _btcpp() -> Any:
    try:
        import behaviortreepy as bt  # type: ignore[import-untyped,import-not-found,unused-ignore]
    except ImportError:
        return None
    return bt.BehaviorTreeFactory().create_tree_from_text(_xml(f'<Script code="{CODE}"/>'))


def run(quick: bool = False) -> dict[str, Any]:
    warmup, count = (20, 200) if quick else (100, 1_000)
    load_start = load_average()
    script, python, theirs = _btcap(False), _btcap(True), _btcpp()
    ticks: dict[str, Callable[[], object]] = {"script": script.tick, "python": python.tick}
    for tree in (script, python):
        assert tree.tick() is btcap.SUCCEEDED
        assert tree.blackboard is not None
        values = tree.blackboard.outputs
        assert (values["b"], values["a"], values["ok"]) == (100.5, 202.0, 1.0), values
    if theirs is not None:
        theirs.tick_exactly_once()
        board = theirs.root_blackboard()
        assert board.get_string("b") == "100.500000", board.get_string("b")
        ticks["btcpp"] = theirs.tick_exactly_once
    samples = time_shape(ticks, warmup, count)
    us = {
        k: percentiles([t / 1000.0 / NODES for t in s["wall"]])["p50"] for k, s in samples.items()
    }
    cpu = {
        k: percentiles([t / 1000.0 / NODES for t in s["cpu"]])["p50"] for k, s in samples.items()
    }
    data: dict[str, Any] = {
        "nodes": NODES,
        "code": CODE,
        "us_per_node": us,
        "cpu_us_per_node": cpu,
        "script_over_python": round(cpu["script"] / cpu["python"], 2),
        "load_average": [load_start, load_average()],
    }
    if "btcpp" in cpu:
        data["btcpp_over_script"] = round(cpu["btcpp"] / cpu["script"], 2)
    print(f"script node ({CODE!r}), CPU µs per node, median:")
    for k in us:
        print(f"  {k:8s} {cpu[k]:7.3f} (wall {us[k]:.3f})")
    print(f"  script / python leaf: {data['script_over_python']}")
    if "btcpp_over_script" in data:
        print(f"  BehaviorTree.CPP / btcap script: {data['btcpp_over_script']}")
    write_result("script", data)
    return data


if __name__ == "__main__":
    import sys

    run(quick="--quick" in sys.argv)
