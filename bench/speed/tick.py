"""Tick cost and memory per node: btcap vs py_trees 2.x (and BehaviorTree.CPP) in one run.

Shapes, built from one neutral description so both libraries get identical trees. In
``flat`` and ``balanced`` every composite is reactive (btcap ``ReactiveSequence``/
``ReactiveFallback``; py_trees ``Sequence``/``Selector`` with ``memory=False``):

- ``flat``: a Sequence of 1000 always-success leaves (1001 nodes).
- ``balanced``: depth 4, fan-out 5, 5, 6, 6 (1 + 5 + 25 + 150 + 900 = 1081 nodes), levels
  alternating Sequence / Fallback from the root. Every node is ticked on every tick: each
  non-last child returns what makes its parent go on (success under a Sequence, failure
  under a Fallback), and a composite's result is then its last child's, so each last
  child passes on what its parent must return. No decorators are needed; the root
  succeeds.
- ``mixed`` and ``mixed_parallel``: 8 seeded random trees of about 1000 nodes each, from
  the generator :mod:`.mixed_trees` states (Sequence/Fallback reactive and with memory,
  decorators, leaves that do a little work and sometimes run; the second also Parallels
  with random thresholds), the same trees in both libraries. One run resets every tree
  (untimed), then ticks each of them for 16 steps; the time of a run is divided by the
  number of nodes that library actually ticked in it (counted beforehand, the same on
  every run since runs start from reset).

Before timing, ticks per node are counted in both libraries (py_trees: the nodes its
``tick()`` generator yields; btcap: calls of each node class's ``tick`` seen by a profile
hook) and every node's resulting state is checked against the description.

Timing: btcap through ``Tree.tick()``, py_trees through ``root.tick_once()`` (no
``BehaviourTree`` visitors or pre/post tick handlers). Each tick is timed by wall clock
(``perf_counter_ns``) and by thread CPU time (``thread_time_ns``); the libraries take
turns in blocks of about 50 ms each, so both are sampled over the same stretch of time.
Reported: the median per tick divided by the node count, in microseconds per node, and
py_trees / btcap as the speed-up (``speedup`` from wall time, ``cpu_speedup`` from CPU
time, which is steadier on a shared machine because preemption does not count).

Peers measured in the same run (:mod:`.tick_peers`): BehaviorTree.CPP 4.8 through
``behaviortreepy`` on ``flat`` and ``balanced`` when installed (taking turns with the
other two), a leaf returning ``State.SUCCEEDED`` against one returning a module constant,
and memory per node at 100,000 nodes, flat and mixed, against py_trees. The load
average is recorded at the start and the end; :func:`.tick_peers.markdown` renders the
README's rows from the result.

Run ``python -m btcap.bench tick [--quick]`` or ``python -m btcap.bench.speed.tick [--quick]``.
"""

from __future__ import annotations

import argparse
import gc
import time
from collections.abc import Callable, Sequence
from importlib.metadata import version
from typing import Any

from btcap.bench.common import percentiles, write_result
from btcap.bench.speed.mixed_trees import MixedRun, MixedSpec, btcap_run, mixed_spec, py_trees_run
from btcap.bench.speed.shapes import (
    FLAT_LEAVES,
    balanced_spec,
    btcap_tree,
    build_btcap,
    build_py_trees,
    flat_spec,
    node_count,
    py_trees_root,
    verify_btcap,
    verify_py_trees,
)
from btcap.bench.speed.tick_peers import (
    MEMORY_NODES,
    btcpp_tick,
    leaf_form_trees,
    load_average,
    markdown,
    memory,
)

__all__ = ["MIXED_SEED", "MIXED_TREES", "run", "time_shape"]

LIBS = ("btcap", "py_trees")
SHAPES = ("flat", "balanced", "mixed", "mixed_parallel")
MIXED_TREES = 8
MIXED_SEED = 1
BLOCK_S = 0.05

# -- measuring ----------------------------------------------------------------------------


def _time_block(
    tick: Callable[[], object], count: int, wall: list[float], cpu: list[float]
) -> None:
    """Append ``count`` per-tick wall and thread-CPU times, in nanoseconds."""
    wall_clock, cpu_clock = time.perf_counter_ns, time.thread_time_ns
    for _ in range(count):
        c0 = cpu_clock()
        t0 = wall_clock()
        tick()
        t1 = wall_clock()
        c1 = cpu_clock()
        wall.append(t1 - t0)
        cpu.append(c1 - c0)


def time_shape(
    ticks: dict[str, Callable[[], object]], warmup: int, count: int, block_s: float = BLOCK_S
) -> dict[str, dict[str, list[float]]]:
    """Per-tick ns (``wall``, ``cpu``) per library, at least ``count`` ticks each.

    The libraries take turns in blocks of about ``block_s`` seconds each (block sizes
    from the warm-up's cost per tick), so both are sampled evenly over the same stretch of
    time and whatever else the machine is doing weighs on both alike.
    """
    per_block: dict[str, int] = {}
    for lib, tick in ticks.items():
        t0 = time.perf_counter()
        for _ in range(warmup):
            tick()
        per_block[lib] = max(1, round(block_s * warmup / (time.perf_counter() - t0)))
    samples: dict[str, dict[str, list[float]]] = {lib: {"wall": [], "cpu": []} for lib in ticks}
    gc.collect()
    while any(len(samples[lib]["wall"]) < count for lib in ticks):
        for lib, tick in ticks.items():
            _time_block(tick, per_block[lib], samples[lib]["wall"], samples[lib]["cpu"])
    return samples


def time_runs(
    runs: dict[str, MixedRun], warmup: int, count: int, block_s: float = BLOCK_S
) -> dict[str, dict[str, list[float]]]:
    """Per-run ns (``wall``, ``cpu``) per library, each run from reset (reset not timed).

    Libraries take turns in blocks of about ``block_s`` seconds, as in :func:`time_shape`.
    """
    wall_clock, cpu_clock = time.perf_counter_ns, time.thread_time_ns
    per_block: dict[str, int] = {}
    for lib, r in runs.items():
        t0 = time.perf_counter()
        for _ in range(warmup):
            r.reset()
            r.run()
        per_block[lib] = max(1, round(block_s * warmup / (time.perf_counter() - t0)))
    samples: dict[str, dict[str, list[float]]] = {lib: {"wall": [], "cpu": []} for lib in runs}
    gc.collect()
    while any(len(samples[lib]["wall"]) < count for lib in runs):
        for lib, r in runs.items():
            wall, cpu = samples[lib]["wall"], samples[lib]["cpu"]
            for _ in range(per_block[lib]):
                r.reset()
                c0 = cpu_clock()
                t0 = wall_clock()
                r.run()
                t1 = wall_clock()
                c1 = cpu_clock()
                wall.append(t1 - t0)
                cpu.append(c1 - c0)
    return samples


# -- the benchmark --------------------------------------------------------------------------


def _table(data: dict[str, Any]) -> str:
    us, cpu, ratio = data["us_per_node"], data["cpu_us_per_node"], data["cpu_speedup"]
    lines = [
        f"load average {data['load_average']['start']} at the start, "
        f"{data['load_average']['end']} at the end",
        f"{'us per node':<14} {'nodes':>5} {'btcap p50':>9} {'cpu':>6} {'py_trees p50':>12} "
        f"{'cpu':>6} {'speed-up':>8} {'cpu':>6}",
        "-" * 72,
    ]
    for shape in SHAPES:
        lines.append(
            f"{shape:<14} {data['nodes'][shape]:>5} {us['btcap'][shape]:>9.3f} "
            f"{cpu['btcap'][shape]:>6.3f} {us['py_trees'][shape]:>12.3f} "
            f"{cpu['py_trees'][shape]:>6.2f} {data['speedup'][shape]:>7.1f}x {ratio[shape]:>5.1f}x"
        )
    t = data["nodes_ticked_per_sample"]
    lines.append(
        "mixed shapes: nodes = all nodes of the trees; per run btcap ticked "
        + ", ".join(f"{t['btcap'][s]} ({s})" for s in SHAPES[2:])
        + " nodes, py_trees "
        + ", ".join(f"{t['py_trees'][s]} ({s})" for s in SHAPES[2:])
    )
    bt = data["btcpp_cpu_ns_per_node"]
    if bt:
        lines.append(
            "BehaviorTree.CPP 4.8 (behaviortreepy, C++ leaves), CPU ns per node: "
            + ", ".join(
                f"{s} {bt[s]:.0f} (btcap {1000 * cpu['btcap'][s]:.0f}, "
                f"{1000 * cpu['btcap'][s] / bt[s]:.2f}x)"
                for s in bt
            )
        )
    else:
        lines.append("BehaviorTree.CPP: behaviortreepy not installed, not measured")
    f = data["leaf_forms_cpu_us_per_node"]
    lines.append(
        f"leaf written `return State.SUCCEEDED`: {f['State.SUCCEEDED']:.3f} us/node CPU, "
        f"`return SUCCEEDED` (module constant): {f['module constant']:.3f} "
        f"({data['leaf_forms_ratio']:.2f}x)"
    )
    m = data["memory"]
    for shape in ("flat", "mixed"):
        lines.append(
            f"memory, {shape} {m['nodes'][shape]} nodes: btcap {m['btcap'][shape]:.0f} B/node, "
            f"py_trees {m['py_trees'][shape]:.0f} B/node ({m['ratio'][shape]:.2f}x)"
        )
    return "\n".join(lines)


def _mixed_runs(shape: str) -> dict[str, MixedRun]:
    specs = _mixed_specs(shape)
    return {"btcap": btcap_run(specs), "py_trees": py_trees_run(specs)}


def run(quick: bool = False) -> dict[str, Any]:
    """Verify the shapes, time the libraries, print a table, write ``bench/results/tick.json``."""
    warmup, count = (20, 200) if quick else (100, 1_000)
    load_start = load_average()
    specs = {"flat": flat_spec(FLAT_LEAVES), "balanced": balanced_spec()}
    us: dict[str, dict[str, float]] = {lib: {} for lib in LIBS}
    us99: dict[str, dict[str, float]] = {lib: {} for lib in LIBS}
    cpu_us: dict[str, dict[str, float]] = {lib: {} for lib in LIBS}
    ticked: dict[str, dict[str, int]] = {lib: {} for lib in LIBS}
    nodes: dict[str, int] = {}
    per_lib_nodes: dict[str, dict[str, int]] = {lib: {} for lib in LIBS}
    all_samples: dict[str, dict[str, dict[str, list[float]]]] = {}
    btcpp: dict[str, float] = {}
    for shape, spec in specs.items():
        n = nodes[shape] = node_count(spec)
        tree = btcap_tree(spec)
        root = py_trees_root(spec)
        verify_btcap(spec, tree)
        verify_py_trees(spec, root)
        ticks: dict[str, Callable[[], object]] = {"btcap": tree.tick, "py_trees": root.tick_once}
        bt_tick = btcpp_tick(spec)
        if bt_tick is not None:
            ticks["btcpp"] = bt_tick
        all_samples[shape] = time_shape(ticks, warmup, count)
        if bt_tick is not None:
            btcpp[shape] = percentiles([t / n for t in all_samples[shape]["btcpp"]["cpu"]])["p50"]
        for lib in LIBS:
            per_lib_nodes[lib][shape] = n
    for shape in ("mixed", "mixed_parallel"):
        runs = _mixed_runs(shape)
        for lib, r in runs.items():
            first, again = r.ticked(), r.ticked()
            assert first == again, f"{lib} {shape}: {first} then {again} nodes ticked from reset"
            per_lib_nodes[lib][shape] = first
        nodes[shape] = sum(len(list(s.walk())) for s in _mixed_specs(shape))
        all_samples[shape] = time_runs(runs, max(2, warmup // 10), max(20, count // 10))
    for shape, samples in all_samples.items():
        for lib in LIBS:
            n = per_lib_nodes[lib][shape]
            p = percentiles([s / 1000.0 / n for s in samples[lib]["wall"]])
            us[lib][shape], us99[lib][shape] = p["p50"], p["p99"]
            cpu_us[lib][shape] = percentiles([s / 1000.0 / n for s in samples[lib]["cpu"]])["p50"]
            ticked[lib][shape] = len(samples[lib]["wall"])
    forms = leaf_form_trees()
    form_samples = time_shape({f: t.tick for f, t in forms.items()}, warmup, count)
    form_us = {
        f: percentiles([s / 1000.0 / (FLAT_LEAVES + 1) for s in v["cpu"]])["p50"]
        for f, v in form_samples.items()
    }
    flat_memory = flat_spec(MEMORY_NODES - 1)
    data: dict[str, Any] = {
        "us_per_node": us,
        "us_per_node_p99": us99,
        "speedup": {s: us["py_trees"][s] / us["btcap"][s] for s in SHAPES},
        "cpu_us_per_node": cpu_us,
        "cpu_speedup": {s: cpu_us["py_trees"][s] / cpu_us["btcap"][s] for s in SHAPES},
        "btcpp_cpu_ns_per_node": btcpp,
        "leaf_forms_cpu_us_per_node": form_us,
        "leaf_forms_ratio": form_us["State.SUCCEEDED"] / form_us["module constant"],
        "memory": memory(flat_memory, build_btcap, build_py_trees),
        "nodes": nodes,
        "nodes_ticked_per_sample": per_lib_nodes,
        "samples": ticked,
        "warmup": warmup,
        "quick": quick,
        "py_trees_version": version("py_trees"),
        "py_trees_tick": "root.tick_once()",
        "btcap_tick": "Tree.tick()",
    }
    data["load_average"] = {"start": load_start, "end": load_average()}
    print(_table(data))
    print(markdown(data))
    path = write_result("tick", data)
    print(f"wrote {path}")
    return data


def _mixed_specs(shape: str) -> list[MixedSpec]:
    parallel = shape == "mixed_parallel"
    return [mixed_spec(MIXED_SEED + i, parallel=parallel) for i in range(MIXED_TREES)]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m btcap.bench.speed.tick", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer ticks, for CI smoke runs")
    args = parser.parse_args(argv)
    run(quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
