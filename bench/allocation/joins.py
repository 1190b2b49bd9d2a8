"""The paper's Fig. 5, measured: does a joining faster robot take the running work over?

``huskies-bebop-joins``: a Bebop (cost factor 1.0, 3 m/s, Explore 10 s) joins at 120 s
while a Husky (2.0, 1 m/s, Explore 60 s) runs the mission's exploration. At the join
the running exploration is auctioned again: the Husky bids what finishing costs it now,
the Bebop what doing it would cost, and the work moves only if the Bebop bids at least
``move_margin`` (0.2) less. A bid is the paper's cost: metres driven times the cost
factor plus the operation's seconds. This prints, per seed, both bids at the join in
those cost units and the same comparison in seconds (the drive at each robot's speed
plus the work), whether the work moved, when the Bebop got its first task, and when
the Husky's exploration ended. ``--bids time`` runs the robots bidding seconds instead
(the scenario's ``bids``), to see the same join priced in time.

Figures come from the run's own events (the simulation manager's records of every
drive with its goal and every operation), so they are what happened, not a model.
"""

from __future__ import annotations

import argparse
import asyncio
from collections.abc import Sequence
from typing import Any, Literal, cast

from btcap.bench.common import write_result
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast
from btcap.sim.world.distance import distance_field, path_length
from btcap.sim.world.manager import SimulationManager

__all__ = ["main", "run"]

SEEDS = (1, 2, 3, 4, 5)


def _goal(detail: str) -> tuple[int, int] | None:
    if not detail.startswith("to ("):
        return None
    row, col = detail[4:].rstrip(")").split(",")
    return int(row), int(col)


async def _one(seed: int, mission: str, bids: str = "paper") -> dict[str, Any]:
    s = load_scenario(builtin_scenarios()["huskies-bebop-joins"])
    s.seed, s.mission = seed, cast(Literal["paper", "pool"], mission)
    s.bids = cast(Literal["paper", "time"], bids)
    join = next(e.at for e in s.events if e.kind == "join")
    joiner = next(e.robot for e in s.events if e.kind == "join")
    models = s.models()
    grid = s.grid()
    goals: dict[str, list[tuple[int, int] | None]] = {}  # each robot's drives' goals, in order
    original = SimulationManager._event

    def event(self: SimulationManager, robot: str, kind: str, **kw: Any) -> Any:
        if kind == "move":
            goals.setdefault(robot, []).append(_goal(kw.get("detail", "")))
        return original(self, robot, kind, **kw)

    SimulationManager._event = event  # type: ignore[method-assign]
    try:
        result = await run_fast(s)
    finally:
        SimulationManager._event = original  # type: ignore[method-assign]
    goal_of: dict[int, tuple[int, int] | None] = {}
    count: dict[str, int] = {}
    for i in result.timeline:  # the manager's order: a robot's n-th drive is its n-th goal
        if i.kind == "move":
            n = count[i.robot] = count.get(i.robot, -1) + 1
            goal_of[id(i)] = goals.get(i.robot, [])[n] if n < len(goals.get(i.robot, [])) else None
    tl = sorted(result.timeline, key=lambda i: i.start)
    # The explorer at the join: an explore under way, or a drive to one.
    running = [
        i for i in tl if i.robot != joiner and i.kind == "explore" and i.start <= join < i.end
    ]
    out: dict[str, Any] = {"seed": seed, "mission": mission, "bids": bids}
    out |= {"moved": result.moved, "mission_s": result.mission_time_s}
    first = next((i for i in tl if i.robot == joiner and i.start >= join), None)
    out["joiner_first_task_after_s"] = None if first is None else round(first.start - join, 1)
    if not running:
        drives = [
            i for i in tl if i.robot != joiner and i.kind == "move" and i.start <= join < i.end
        ]
        nxt = {
            d.robot: next(
                (i for i in tl if i.robot == d.robot and i.kind == "explore" and i.start >= d.end),
                None,
            )
            for d in drives
        }
        running = [x for x in nxt.values() if x is not None and x.start - join < 60]
        phase = "driving"
    else:
        phase = "exploring"
    if not running:
        out["phase"] = "no exploration under way"
        return out
    ex = running[0]
    husky = models[next(r.model for r in s.robots if r.name == ex.robot)]
    bebop = models[next(r.model for r in s.robots if r.name == joiner)]
    # where that exploration is: the husky's last drive that ended by its start
    drive = [i for i in tl if i.robot == ex.robot and i.kind == "move" and i.end <= ex.start + 1]
    drive_left_m = max(0.0, drive[-1].end - join) * husky.speed_mps if drive else 0.0
    worked = max(0.0, join - ex.start)
    dur_h = husky.operation("explore").duration_s
    dur_b = bebop.operation("explore").duration_s
    h_cost = drive_left_m * husky.cost_factor + max(0.0, dur_h - worked)
    h_time = drive_left_m / husky.speed_mps + max(0.0, dur_h - worked)
    goal = goal_of.get(id(drive[-1])) if drive else None
    bebop_m = (
        path_length(distance_field(grid.free, goal), grid.start, grid.cell_size_m) if goal else None
    )
    out |= {
        "phase": phase,
        "explorer": ex.robot,
        "explore_ends_after_s": round(ex.end - join, 1),
        "husky_bid_cost": round(h_cost, 1),
        "husky_left_s": round(h_time, 1),
    }
    if bebop_m is not None:
        out["bebop_bid_cost"] = round(bebop_m * bebop.cost_factor + dur_b, 1)
        out["bebop_takes_s"] = round(bebop_m / bebop.speed_mps + dur_b, 1)
    return out


def run(
    quick: bool = False,
    *,
    seeds: Sequence[int] | None = None,
    missions: Sequence[str] = ("paper",),
    bids: str = "paper",
) -> dict[str, Any]:
    seeds = list(seeds) if seeds is not None else list(SEEDS[:2] if quick else SEEDS)
    rows = [asyncio.run(_one(seed, m, bids)) for m in missions for seed in seeds]
    for r in rows:
        print(r)
    out = {"rows": rows}
    write_result("joins", out)
    return out


def main(argv: Sequence[str] | None = None, *, quick: bool = False) -> dict[str, Any]:
    from btcap.bench.allocation.args import seed_list

    p = argparse.ArgumentParser(prog="python -m btcap.bench.allocation.joins", description=__doc__)
    p.add_argument("--seeds", type=seed_list)
    p.add_argument("--missions", default="paper")
    p.add_argument("--bids", choices=("paper", "time"), default="paper")
    a = p.parse_args(argv)
    return run(quick, seeds=a.seeds, missions=a.missions.split(","), bids=a.bids)


if __name__ == "__main__":
    main()
