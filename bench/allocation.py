"""Allocation quality of the real assignment code against the exact optimum.

On seeded random instances (robots and tasks on a cave map; cost = path length x the
robot's cost factor + the task's duration on that robot, as bids are computed in the
mission), a team of agents runs in one process on a virtual clock: one robot per agent,
each bidding those costs, and an origin whose mission holds one capability node per task
(a task never ends, so each robot does at most one). Each strategy of the auctioneer
(``arrival``, ``auction``, ``sequential``, ``optimal``; see
``btcap.team.core.planning``) assigns them through real calls for bids, bids and awards.

- **static**: every task is asked for at once; the reference is the optimum of
  ``scipy.optimize.linear_sum_assignment``.
- **arrivals**: tasks arrive one by one at seeded times; **failures**: every task at once,
  then robots holding one fail (cut off the network) at seeded times and their tasks are
  re-auctioned; **joins**: every task at once to as many robots, then the spare robots
  join one by one at seeded times (running work may move to them). All run with
  re-evaluation of running work (``reevaluate_s`` 30 s, ``move_margin`` 0.2, the
  defaults; ``auction-fixed``: the auction without it) until it settled. The reference is
  the *offline optimum with hindsight*: the least total cost of giving every task a robot
  that never fails, knowing all tasks, failures and joins in advance. Only the final
  allocation is priced (work done before a move or a failure is not).

Reported: the ratio of total costs to the reference (1.0 = optimal), and of makespans
(the largest cost any robot took on, against that in the reference's assignment); next
to each dynamic ratio, the failures any robot declared of a robot not failed on purpose
(``ff``: false failures, summed over the instances; 0 means the team did not flap).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from contextlib import AsyncExitStack
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from btcap import AlwaysRunning, ReactiveSequence, Tree
from btcap.actors import ManualClock
from btcap.bench.common import write_result
from btcap.sim.distance import DistanceCache, path_length
from btcap.sim.grid import GridMap
from btcap.team.capabilities.capability import Capability, CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.members import TeamEvent
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

__all__ = ["Events", "allocate", "ratios", "run"]

TASK = CapabilityInterface("Task", inputs={"task": int}, description="go and do task #task")
STRATEGIES = ("arrival", "auction", "sequential", "consensus", "optimal")
#: Strategy columns of the dynamic cases: (label, strategy, re-evaluation period).
DYNAMIC = (
    ("arrival", "arrival", 30.0),
    ("auction", "auction", 30.0),
    ("auction-fixed", "auction", None),
    ("sequential", "sequential", 30.0),
    ("consensus", "consensus", 30.0),
    ("optimal", "optimal", 30.0),
)
STEP_S = 0.5  # how often the origin ticks its mission (clock seconds)
SETTLE_S = 35.0  # after the last event: failure detection and one re-evaluation

Costs = np.ndarray[Any, np.dtype[np.float64]]


@dataclass(frozen=True, slots=True)
class Events:
    """When each task arrives, when a robot holding a task fails, and when the last
    robots join, one each (clock seconds)."""

    arrive: tuple[float, ...]
    fail_at: tuple[float, ...] = ()
    join_at: tuple[float, ...] = ()


def _instance(grid: GridMap, rng: np.random.Generator, robots: int, tasks: int) -> Costs:
    cache = DistanceCache(grid.free, maxsize=tasks + 1)
    starts = grid.random_free_cells(robots, rng, replace=True)
    goals = grid.random_free_cells(tasks, rng, replace=True)
    factor = rng.choice([1.0, 1.25, 2.0], size=robots)
    duration = rng.uniform(2.0, 60.0, size=(robots, tasks))
    cost = np.empty((robots, tasks))
    for t, goal in enumerate(goals):
        field = cache.get(goal)
        for r, start in enumerate(starts):
            cost[r, t] = path_length(field, start, grid.cell_size_m) * factor[r] + duration[r, t]
    return cost


def _implementation(costs: dict[int, float]) -> Implementation:
    def build() -> Tree:
        bridge, _ = TASK.bridge_types()
        return Tree(ReactiveSequence("impl", children=[bridge(name="in"), AlwaysRunning("work")]))

    return Implementation("do-task", TASK, build, (), lambda inputs: costs[inputs["task"]])


async def allocate(
    cost: Costs,
    strategy: str,
    events: Events,
    reevaluate_s: float | None,
    seed: int,
    *,
    false: list[tuple[str, str]] | None = None,
) -> tuple[list[int], set[int]]:
    """Which robot the real team has on each task in the end (-1: none), and which robots
    failed (each the holder of a task, picked with ``seed``). ``false`` collects
    (observer, robot) of every failure declared of a robot that was not failed on
    purpose, by one that was not either (a flapping team would make the ratios
    meaningless)."""
    robots, tasks = cost.shape
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry(), encode=False)
    cfg = AgentConfig(
        heartbeat_s=1.0, failure_timeout_s=3.0, reevaluate_s=reevaluate_s, strategy=strategy
    )
    rng = np.random.default_rng(seed)
    names = [f"r{r:02d}" for r in range(robots)]
    failed: set[int] = set()
    agents = [
        Agent(
            name,
            transport=net.transport(name),
            clock=clock,
            implementations=[_implementation({t: float(cost[r, t]) for t in range(tasks)})],
            config=cfg,
        )
        for r, name in enumerate(names)
    ]
    joining = list(zip(sorted(events.join_at), agents[robots - len(events.join_at) :], strict=True))

    def watch(agent: Agent) -> None:
        def seen(event: TeamEvent, robot: str) -> None:
            if false is None or event is not TeamEvent.FAILED:
                return
            cut = {names[r] for r in failed}  # cut off on purpose: they fail the others
            if robot not in cut and agent.robot not in cut:
                false.append((agent.robot, robot))

        agent.team.subscribe(seen)

    async with clock.autojump(), AsyncExitStack() as stack:
        for agent in agents[: robots - len(joining)]:
            await stack.enter_async_context(agent)
            watch(agent)
        origin = await stack.enter_async_context(
            Agent("origin", transport=net.transport("origin"), clock=clock, config=cfg)
        )
        watch(origin)
        while len(origin.repository.providers(TASK.identity)) < robots - len(joining):
            await clock.sleep(0.1)
        nodes: list[Capability] = [
            TASK.node_type()(f"t{t}", inputs={"task": t}) for t in range(tasks)
        ]
        trees: list[Tree] = []
        fails = sorted(events.fail_at)
        start = clock.now()
        last = max((*events.arrive, *fails, *events.join_at))
        while True:
            now = clock.now() - start
            while len(trees) < tasks and events.arrive[len(trees)] <= now:
                trees.append(origin.mission(nodes[len(trees)]))
            while fails and fails[0] <= now:
                fails.pop(0)
                held = sorted(
                    {names.index(n.execution.robot) for n in nodes if n.execution} - failed
                )
                if held:
                    victim = int(rng.choice(held))
                    failed.add(victim)
                    net.isolate(names[victim])
            while joining and joining[0][0] <= now:
                watch(await stack.enter_async_context(joining.pop(0)[1]))
            for tree in trees:
                tree.tick()
            lost = {names[r] for r in failed}
            settled = all(n.execution is not None and n.execution.robot not in lost for n in nodes)
            if settled and now >= last + (SETTLE_S if reevaluate_s is not None else 0.0):
                break
            await clock.sleep(STEP_S)
        final = [names.index(n.execution.robot) if n.execution else -1 for n in nodes]
        for tree in trees:
            await tree.shutdown()
    return final, failed


def _events(rng: np.random.Generator, case: str, tasks: int, robots: int) -> Events:
    """Seeded events of ``case``; ``robots`` (those failing or joining) is its size."""
    at_once = (0.0,) * tasks
    if case == "arrivals":
        return Events(tuple(sorted(rng.uniform(0.0, 60.0, size=tasks).round(2))))
    times = tuple(rng.uniform(5.0, 60.0, size=robots).round(2))
    if case == "failures":
        return Events(at_once, fail_at=times)
    if case == "joins":
        return Events(at_once, join_at=times)
    return Events(at_once)


def ratios(cost: Costs, final: list[int], alive: list[int]) -> tuple[float, float]:
    """Total cost and makespan of ``final`` over the hindsight optimum's (robots ``alive``)."""
    sub = cost[alive]
    rows, cols = linear_sum_assignment(sub)
    best, span = float(sub[rows, cols].sum()), float(sub[rows, cols].max())
    taken = [float(cost[r, t]) for t, r in enumerate(final) if r >= 0]
    if len(taken) < cost.shape[1]:  # a task left without a robot: no ratio would be honest
        return float("inf"), float("inf")
    return sum(taken) / best, max(taken) / span


def _summary(table: dict[str, list[float]]) -> dict[str, dict[str, float]]:
    return {
        s: {"mean": round(statistics.mean(v), 4), "max": round(max(v), 4)} for s, v in table.items()
    }


def _print(
    title: str,
    rows: dict[str, dict[str, dict[str, float]]],
    columns: list[str],
    false: dict[str, dict[str, int]] | None = None,
) -> None:
    """A table of mean (max) ratios; with ``false``, each cell also shows the false
    failures declared in its runs (``ff``)."""
    width = 19 if false is None else 25
    print(title)
    print(f"{'':>15} " + " ".join(f"{s:>{width}}" for s in columns))
    for key, by in rows.items():
        cells = []
        for s in columns:
            cell = f"{by[s]['mean']:8.3f} (max {by[s]['max']:5.2f})"
            if false is not None:
                cell += f" ff {false[key][s]:<2}"
            cells.append(f"{cell:>{width}}")
        print(f"{key:>15} {' '.join(cells)}")


def run(quick: bool = False) -> dict[str, Any]:
    grid = GridMap.generate_cave(80, 60, seed=3)
    sizes = [(5, 5), (10, 10)] if quick else [(5, 5), (10, 10), (20, 20)]
    instances = 5 if quick else 20
    robots, tasks, failures = (10, 6, 2) if quick else (25, 20, 3)
    dyn_instances = 2 if quick else 10
    out: dict[str, Any] = {"instances": instances, "cost_ratio": {}, "makespan_ratio": {}}
    t0 = time.perf_counter()
    for r, t in sizes:
        by_cost: dict[str, list[float]] = {s: [] for s in STRATEGIES}
        spans: dict[str, list[float]] = {s: [] for s in STRATEGIES}
        for seed in range(instances):
            cost = _instance(grid, np.random.default_rng(seed), r, t)
            for strategy in STRATEGIES:
                final, _ = asyncio.run(
                    allocate(
                        cost,
                        strategy,
                        _events(np.random.default_rng(seed), "static", t, 0),
                        None,
                        seed,
                    )
                )
                ratio, span = ratios(cost, final, list(range(r)))
                by_cost[strategy].append(ratio)
                spans[strategy].append(span)
        out["cost_ratio"][f"{r}x{t}"] = _summary(by_cost)
        out["makespan_ratio"][f"{r}x{t}"] = _summary(spans)
    labels = [label for label, _s, _p in DYNAMIC]
    dynamic: dict[str, Any] = {"robots": robots, "tasks": tasks, "failures": failures}
    dynamic |= {"instances": dyn_instances, "cost_ratio": {}, "makespan_ratio": {}}
    dynamic["false_failures"] = {}
    for case, size in (("arrivals", 0), ("failures", failures), ("joins", robots - tasks)):
        by_cost = {label: [] for label in labels}
        spans = {label: [] for label in labels}
        false: dict[str, list[tuple[str, str]]] = {label: [] for label in labels}
        for seed in range(dyn_instances):
            rng = np.random.default_rng(1000 + seed)
            cost = _instance(grid, rng, robots, tasks)
            events = _events(rng, case, tasks, size)
            for label, strategy, period in DYNAMIC:
                final, failed = asyncio.run(
                    allocate(cost, strategy, events, period, seed, false=false[label])
                )
                alive = [i for i in range(robots) if i not in failed]
                ratio, span = ratios(cost, final, alive)
                by_cost[label].append(ratio)
                spans[label].append(span)
        dynamic["cost_ratio"][case] = _summary(by_cost)
        dynamic["makespan_ratio"][case] = _summary(spans)
        dynamic["false_failures"][case] = {label: len(v) for label, v in false.items()}
    out["dynamic"] = dynamic
    out["seconds"] = round(time.perf_counter() - t0, 2)
    print(f"static: every task at once; {instances} seeded instances; reference: the optimum")
    _print("total cost / optimum", out["cost_ratio"], list(STRATEGIES))
    _print("makespan / the optimum's", out["makespan_ratio"], list(STRATEGIES))
    print(
        f"dynamic: {robots} robots x {tasks} tasks, arriving over 60 s, or with {failures} "
        f"holders failing, or with {robots - tasks} robots joining; {dyn_instances} "
        "instances; reference: the optimum with hindsight"
    )
    ff = dynamic["false_failures"]
    _print("total cost / hindsight optimum (ff: false failures)", dynamic["cost_ratio"], labels, ff)
    _print("makespan / the hindsight optimum's", dynamic["makespan_ratio"], labels, ff)
    print(f"({out['seconds']} s)")
    write_result("allocation", out)
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    run(quick=p.parse_args().quick)
