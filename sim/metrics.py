"""What a mission run produced: times, per-robot work, the timeline, as one JSON-able value."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import msgspec

from btcap import State, Tree
from btcap.team.capability import Capability

if TYPE_CHECKING:
    from btcap.sim.manager import SimulationManager
    from btcap.sim.scenario import Scenario
    from btcap.sim.store import MissionState
    from btcap.team.agent import Agent

__all__ = ["Interval", "Mark", "MissionResult", "RobotStats", "collect"]


class Interval(msgspec.Struct):
    """One piece of work on the timeline (seconds since the mission started)."""

    robot: str
    kind: str
    start: float
    end: float
    ok: bool
    target: int = -1


class Mark(msgspec.Struct):
    """A team change on the timeline: joined, left, failed, down (sim failure), up."""

    time: float
    event: str
    robot: str


class RobotStats(msgspec.Struct):
    model: str
    busy_s: float
    present_s: float
    utilisation: float
    tasks: dict[str, int]
    distance_m: float


class MissionResult(msgspec.Struct):
    scenario: str
    completed: bool
    mission_time_s: float
    summary: dict[str, float]
    robots: dict[str, RobotStats]
    auctions: int
    reassignments: int
    failures_survived: int
    assignments: dict[str, list[str]]
    timeline: list[Interval]
    marks: list[Mark]
    moved: int = 0  # running work moved to a cheaper robot that joined (rebid_on_join)

    def to_json(self) -> bytes:
        return msgspec.json.format(msgspec.json.encode(self), indent=2)


def _present_s(s: Scenario, robot: str, end: float) -> float:
    present = robot in {r.name for r in s.initially_present()}
    since = 0.0
    total = 0.0
    for e in sorted((e for e in s.events if e.robot == robot), key=lambda e: e.at):
        at = min(e.at, end)
        if e.kind == "join" and not present:
            present, since = True, at
        elif e.kind == "leave" and present:
            total += at - since
            present = False
        elif e.kind == "fail" and present:
            total += at - since
            since = min(e.at + e.duration, end)
    if present:
        total += max(0.0, end - since)
    return total


def collect(
    s: Scenario,
    state: MissionState,
    manager: SimulationManager,
    tree: Tree,
    operator: Agent,
    started: float,
    ended: float,
    final: State,
    marks: list[tuple[float, str, str]],
) -> MissionResult:
    """Gather the result of a finished (or timed-out) run."""
    duration = ended - started
    timeline = [
        Interval(
            e.robot,
            e.kind,
            e.start - started,
            (e.end if e.end is not None else ended) - started,
            bool(e.ok),
            e.target,
        )
        for e in manager.events
        if e.end is None or e.end >= started
    ]
    robots: dict[str, RobotStats] = {}
    for r in s.robots:
        mine = [i for i in timeline if i.robot == r.name]
        busy = sum(max(0.0, i.end - max(0.0, i.start)) for i in mine)
        present = _present_s(s, r.name, duration)
        tasks: dict[str, int] = {}
        for i in mine:
            if i.kind != "move" and i.ok:
                tasks[i.kind] = tasks.get(i.kind, 0) + 1
        idx = manager.robots[r.name].index
        robots[r.name] = RobotStats(
            r.model,
            round(busy, 3),
            round(present, 3),
            round(busy / present, 4) if present > 0 else 0.0,
            tasks,
            round(float(manager.world.travelled_m[idx]), 2),
        )
    assignments = {n.path: list(n.assignments) for n in tree.nodes() if isinstance(n, Capability)}
    survived = sum(1 for e in s.events if e.kind in ("fail", "leave") and e.at < duration)
    completed = final is State.SUCCEEDED and state.mission_complete
    return MissionResult(
        s.name,
        completed,
        round(duration, 3),
        {k: float(v) for k, v in state.summary().items()},
        robots,
        operator.auctioneer.stats.auctions,
        operator.mission_control.stats.lost,
        survived if completed else 0,
        assignments,
        timeline,
        # Team changes only: "changed" (a member's capabilities changed) is no mark.
        [Mark(round(t - started, 3), ev, robot) for t, ev, robot in marks if ev != "changed"],
        operator.mission_control.stats.moved,
    )


def as_dict(result: MissionResult) -> dict[str, Any]:
    return msgspec.to_builtins(result)  # type: ignore[no-any-return]
