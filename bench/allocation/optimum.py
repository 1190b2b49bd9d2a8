"""Allocation quality of the real assignment code against the exact optimum.

On seeded random instances (robots and tasks on a cave map; cost = path length x the
robot's cost factor + the task's duration on that robot, as bids are computed in the
mission), a team of agents runs in one process on a virtual clock: one robot per agent,
each bidding those costs, and an origin whose mission holds one capability node per task
(a task never ends, so each robot does at most one). Every registered strategy
(``btcap.team.allocation.strategies.names()``: the built-ins and installed plug-ins)
assigns them through its real messages.

- **static**: every task is asked for at once, at 5x5, 20x20, 50x50 robots x tasks and
  10x20 (tasks outnumber robots: the first wave is priced, ten tasks wait); the
  reference is the optimum of ``scipy.optimize.linear_sum_assignment`` (for 10x20 the
  cheapest ten robot-task pairs that can run together). Next to each ratio: the
  allocation messages sent (calls for bids, bids, awards, consensus traffic; not
  membership or execution traffic) and the process CPU time, from the first call for
  bids until the allocation settled, per instance.
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
from collections.abc import Sequence
from contextlib import AsyncExitStack
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from btcap import AlwaysRunning, ReactiveSequence, Tree
from btcap.actors import ManualClock
from btcap.bench.allocation.args import load_map, seed_list
from btcap.bench.common import write_result
from btcap.sim.world.distance import DistanceCache, path_length
from btcap.sim.world.grid import GridMap
from btcap.team.allocation.strategies import names as strategy_names
from btcap.team.capabilities.capability import Capability, CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.members import TeamEvent
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork
from btcap.transports.codec import Envelope

__all__ = [
    "Allocation",
    "Costs",
    "Events",
    "allocate",
    "main",
    "ratios",
    "run",
    "seeded_events",
    "seeded_instance",
]

TASK = CapabilityInterface("Task", inputs={"task": int}, description="go and do task #task")
#: The static rows: robots x tasks.
SIZES = ((5, 5), (20, 20), (50, 50), (10, 20))
QUICK_SIZES = ((5, 5), (10, 10), (5, 10))
#: Traffic that is not allocation (membership, gossip, the executions themselves).
NOT_ALLOCATION = frozenset(
    {
        "Heartbeat", "Roster", "RosterRequest", "ActivityQuery", "Activity", "Goodbye",
        "ProbeRequest", "Vouch", "RepositoryState", "RepositoryQuery", "ExecutionInputs",
        "ExecutionStatus", "PauseExecution", "CancelExecution", "KeepAlive", "CostChanged",
    }
)  # fmt: skip
STEP_S = 0.5  # how often the origin ticks its mission (clock seconds)
SETTLE_S = 35.0  # after the last event: failure detection and one re-evaluation

Costs = np.ndarray[Any, np.dtype[np.float64]]


def dynamic_columns() -> list[tuple[str, str, float | None]]:
    """Strategy columns of the dynamic cases: (label, strategy, re-evaluation period);
    ``auction-fixed`` is the paper's auction without re-evaluation."""
    cols: list[tuple[str, str, float | None]] = [(s, s, 30.0) for s in strategy_names()]
    return [*cols, ("auction-fixed", "auction", None)]


class _Counting(InProcessNetwork):
    """The in-process network, counting allocation messages while ``counting``."""

    counting = False
    messages = 0

    def _route(self, src: Any, env: Envelope) -> None:
        if self.counting and type(env.msg).__name__ not in NOT_ALLOCATION:
            self.messages += 1
        super()._route(src, env)


@dataclass(frozen=True, slots=True)
class Allocation:
    """What a team did with an instance: the robot on each task in the end (-1: none),
    the robots failed on purpose, and the allocation messages and process CPU seconds
    from the first call for bids until it settled."""

    final: list[int]
    failed: set[int]
    messages: int = 0
    cpu_s: float = 0.0


@dataclass(frozen=True, slots=True)
class Events:
    """When each task arrives, when a robot holding a task fails, and when the last
    robots join, one each (clock seconds)."""

    arrive: tuple[float, ...]
    fail_at: tuple[float, ...] = ()
    join_at: tuple[float, ...] = ()


def seeded_instance(grid: GridMap, rng: np.random.Generator, robots: int, tasks: int) -> Costs:
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
) -> Allocation:
    """Which robot the real team has on each task in the end (-1: none; with more tasks
    than robots, the tasks beyond the first wave), and which robots failed (each the
    holder of a task, picked with ``seed``). ``false`` collects
    (observer, robot) of every failure declared of a robot that was not failed on
    purpose, by one that was not either (a flapping team would make the ratios
    meaningless)."""
    robots, tasks = cost.shape
    clock = ManualClock()
    net = _Counting(protocol_registry(), encode=False)
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
        net.counting = True
        cpu = time.process_time()
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
            busy = {n.execution.robot for n in nodes if n.execution is not None} - lost
            room = min(tasks, len(agents) - len(joining) - len(failed))
            settled = len(busy) >= room
            if settled and now >= last + (SETTLE_S if reevaluate_s is not None else 0.0):
                break
            await clock.sleep(STEP_S)
        cpu = time.process_time() - cpu
        net.counting = False
        final = [names.index(n.execution.robot) if n.execution else -1 for n in nodes]
        for tree in trees:
            await tree.shutdown()
    return Allocation(final, failed, net.messages, cpu)


def seeded_events(rng: np.random.Generator, case: str, tasks: int, robots: int) -> Events:
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
    """Total cost and makespan of ``final`` over the hindsight optimum's (robots ``alive``;
    with more tasks than robots, the optimum of the first wave: as many tasks as robots)."""
    sub = cost[alive]
    rows, cols = linear_sum_assignment(sub)
    best, span = float(sub[rows, cols].sum()), float(sub[rows, cols].max())
    taken = [float(cost[r, t]) for t, r in enumerate(final) if r >= 0]
    if len(taken) < min(cost.shape[1], len(alive)):  # work left undone: no honest ratio
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


def _static(
    grid: GridMap, sizes: Sequence[tuple[int, int]], seeds: Sequence[int], strategies: list[str]
) -> dict[str, Any]:
    """Every task at once: each strategy's cost ratio, makespan ratio, messages and CPU."""
    out: dict[str, Any] = {"cost_ratio": {}, "makespan_ratio": {}, "messages": {}, "cpu_ms": {}}
    for r, t in sizes:
        by_cost: dict[str, list[float]] = {s: [] for s in strategies}
        spans: dict[str, list[float]] = {s: [] for s in strategies}
        msgs: dict[str, list[float]] = {s: [] for s in strategies}
        cpu: dict[str, list[float]] = {s: [] for s in strategies}
        for seed in seeds:
            cost = seeded_instance(grid, np.random.default_rng(seed), r, t)
            for strategy in strategies:
                got = asyncio.run(allocate(cost, strategy, Events((0.0,) * t), None, seed))
                ratio, span = ratios(cost, got.final, list(range(r)))
                by_cost[strategy].append(ratio)
                spans[strategy].append(span)
                msgs[strategy].append(got.messages)
                cpu[strategy].append(got.cpu_s * 1e3)
        key = f"{r}x{t}"
        out["cost_ratio"][key] = _summary(by_cost)
        out["makespan_ratio"][key] = _summary(spans)
        out["messages"][key] = {s: round(statistics.mean(v), 1) for s, v in msgs.items()}
        out["cpu_ms"][key] = {s: round(statistics.mean(v), 1) for s, v in cpu.items()}
    return out


def _dynamic(grid: GridMap, quick: bool, seeds: Sequence[int]) -> dict[str, Any]:
    """Tasks arriving, holders failing, robots joining, with re-evaluation."""
    robots, tasks, failures = (10, 6, 2) if quick else (25, 20, 3)
    columns = dynamic_columns()
    labels = [label for label, _s, _p in columns]
    dynamic: dict[str, Any] = {"robots": robots, "tasks": tasks, "failures": failures}
    dynamic |= {"instances": len(seeds), "cost_ratio": {}, "makespan_ratio": {}}
    dynamic["false_failures"] = {}
    for case, size in (("arrivals", 0), ("failures", failures), ("joins", robots - tasks)):
        by_cost: dict[str, list[float]] = {label: [] for label in labels}
        spans: dict[str, list[float]] = {label: [] for label in labels}
        false: dict[str, list[tuple[str, str]]] = {label: [] for label in labels}
        for seed in seeds:
            rng = np.random.default_rng(1000 + seed)
            cost = seeded_instance(grid, rng, robots, tasks)
            events = seeded_events(rng, case, tasks, size)
            for label, strategy, period in columns:
                got = allocate(cost, strategy, events, period, seed, false=false[label])
                done = asyncio.run(got)
                alive = [i for i in range(robots) if i not in done.failed]
                ratio, span = ratios(cost, done.final, alive)
                by_cost[label].append(ratio)
                spans[label].append(span)
        dynamic["cost_ratio"][case] = _summary(by_cost)
        dynamic["makespan_ratio"][case] = _summary(spans)
        dynamic["false_failures"][case] = {label: len(v) for label, v in false.items()}
    return dynamic


def _print_static(out: dict[str, Any], strategies: list[str]) -> None:
    """One row per size: each strategy's mean (worst) ratio, messages and CPU ms."""
    print("total cost / optimum: mean (worst); allocation messages; CPU ms, per instance")
    width = 30
    print(f"{'':>7} " + " ".join(f"{s:>{width}}" for s in strategies))
    for key, by in out["cost_ratio"].items():
        cells = []
        for s in strategies:
            msgs, cpu = out["messages"][key][s], out["cpu_ms"][key][s]
            cell = f"{by[s]['mean']:.3f} ({by[s]['max']:.3f}) {msgs:6.0f} {cpu:7.1f}"
            cells.append(f"{cell:>{width}}")
        print(f"{key:>7} {' '.join(cells)}")


def run(
    quick: bool = False,
    *,
    seeds: Sequence[int] | None = None,
    grid: GridMap | None = None,
    sizes: Sequence[tuple[int, int]] | None = None,
    dynamic: bool = True,
) -> dict[str, Any]:
    """The static rows for every strategy and (``dynamic``) the dynamic cases; by
    default on the cave of seed 3 and seeds 0-19 (0-4 quick)."""
    grid = grid if grid is not None else GridMap.generate_cave(80, 60, seed=3)
    sizes = sizes if sizes is not None else (QUICK_SIZES if quick else SIZES)
    seeds = list(seeds) if seeds is not None else list(range(5 if quick else 20))
    strategies = strategy_names()
    out: dict[str, Any] = {"instances": len(seeds), "seeds": [seeds[0], seeds[-1]]}
    out["map"] = grid.source
    t0 = time.perf_counter()
    out |= _static(grid, sizes, seeds, strategies)
    print(f"static: every task at once; {len(seeds)} instances on {grid.source}")
    _print_static(out, strategies)
    if dynamic:
        dyn_seeds = seeds[: 2 if quick else 10]
        out["dynamic"] = d = _dynamic(grid, quick, dyn_seeds)
        labels = [label for label, _s, _p in dynamic_columns()]
        print(
            f"dynamic: {d['robots']} robots x {d['tasks']} tasks, arriving over 60 s, or "
            f"with {d['failures']} holders failing, or with {d['robots'] - d['tasks']} "
            f"robots joining; {len(dyn_seeds)} instances; reference: the optimum with hindsight"
        )
        ff = d["false_failures"]
        _print("total cost / hindsight optimum (ff: false failures)", d["cost_ratio"], labels, ff)
        _print("makespan / the hindsight optimum's", d["makespan_ratio"], labels, ff)
    out["seconds"] = round(time.perf_counter() - t0, 2)
    print(f"({out['seconds']} s)")
    write_result("allocation", out)
    return out


def main(argv: Sequence[str] | None = None, *, quick: bool = False) -> dict[str, Any]:
    """The command line: ``--seeds``, ``--map``, ``--sizes``, ``--static``."""
    p = argparse.ArgumentParser(prog="python -m btcap.bench allocation", description=__doc__)
    p.add_argument("--quick", action="store_true", default=quick)
    p.add_argument("--seeds", type=seed_list, help="instance seeds, e.g. 1000-1019")
    p.add_argument("--map", type=load_map, help="cave:SEED or a map file (.npy/.png/.txt)")
    p.add_argument("--sizes", help="robots x tasks rows, e.g. 20x20,10x20")
    p.add_argument("--static", action="store_true", help="only the static rows")
    a = p.parse_args(argv)
    sizes = None
    if a.sizes:
        try:
            sizes = [(int(r), int(t)) for r, t in (x.split("x") for x in a.sizes.split(","))]
        except ValueError:
            p.error(f"--sizes {a.sizes!r}: expected ROBOTSxTASKS rows like 20x20,10x20")
    return run(a.quick, seeds=a.seeds, grid=a.map, sizes=sizes, dynamic=not a.static)


if __name__ == "__main__":
    main()
