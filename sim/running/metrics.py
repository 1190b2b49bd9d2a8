"""What a mission run produced: times, per-robot work, the timeline, as one JSON-able value."""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING

import msgspec

from btcap import Node, State, Tree
from btcap.bt.state import DONE
from btcap.team.capabilities.capability import Capability

if TYPE_CHECKING:
    from btcap.sim.mission.scenario import Scenario
    from btcap.sim.world.manager import SimulationManager
    from btcap.sim.world.store import MissionState
    from btcap.team.runtime.agent import Agent

__all__ = [
    "Interval",
    "Mark",
    "MissionLog",
    "MissionResult",
    "RobotError",
    "RobotStats",
    "collect",
    "idle_robots_note",
]


class Interval(msgspec.Struct):
    """One piece of work on the timeline (seconds since the mission started)."""

    robot: str
    kind: str
    start: float
    end: float
    ok: bool
    target: int = -1


class Mark(msgspec.Struct):
    """A team change on the timeline: joined, left, failed, down (sim failure), up, crashed."""

    time: float
    event: str
    robot: str


class RobotError(msgspec.Struct):
    """A robot that crashed (its runtime raised, its process died) or never came up.

    ``time`` is clock time while the mission runs and seconds since it started in a
    :class:`MissionResult`.
    """

    time: float
    robot: str
    error: str


class RobotStats(msgspec.Struct):
    model: str
    busy_s: float
    present_s: float
    utilisation: float
    tasks: dict[str, int]
    distance_m: float


class MissionResult(msgspec.Struct):
    """A mission run. ``executions_lost``: executions whose executor was lost (it failed,
    left or crashed); ``reassigned``: capability runs that moved to another robot after
    such a loss; ``moved``: running work re-evaluated and moved to a clearly cheaper
    robot; ``robot_failures`` and ``robots_left``: the scenario's fail and
    leave events that happened while the mission ran, whether or not the robot was busy;
    ``errors``: robots that crashed; ``timed_out``: the time limit ended the run;
    ``exchanged``: exchanges of running work between busy robots; ``undone``: moves and
    exchanges that handed a task back to the robot it left within 60 s; ``held_back``:
    those the hold-down refused; ``foreseen_back``: exchanges not made because a robot
    would have taken its task back once free (see :mod:`btcap.team.core.handovers`)."""

    scenario: str
    completed: bool
    mission_time_s: float
    summary: dict[str, float]
    robots: dict[str, RobotStats]
    auctions: int
    executions_lost: int
    reassigned: int
    robot_failures: int
    robots_left: int
    assignments: dict[str, list[str]]
    timeline: list[Interval]
    marks: list[Mark]
    moved: int = 0
    errors: list[RobotError] = []
    timed_out: bool = False
    interrupted: bool = False
    """Stopped early by the user (SIGINT or SIGTERM): the figures are what was done so far."""
    exchanged: int = 0
    undone: int = 0
    held_back: int = 0
    foreseen_back: int = 0

    def to_json(self) -> bytes:
        return msgspec.json.format(msgspec.json.encode(self), indent=2)


class MissionLog:
    """What the runner sees while a mission runs, beside the simulation's own record.

    Team marks and the scenario events applied, and, as an observer of the mission tree
    (``tree.observe(log)``), re-assignments: a capability that had an executor and falls
    back to unassigned lost it; if it is next assigned to another robot, that run was
    re-assigned. A move to a joiner never passes through unassigned, so it is no loss.
    """

    def __init__(self) -> None:
        self.marks: list[tuple[float, str, str]] = []
        self.applied: Counter[str] = Counter()
        self.reassigned = 0
        self._holder: dict[int, str] = {}
        self._lost: dict[int, str] = {}

    def mark(self, time: float, event: str, robot: str) -> None:
        self.marks.append((time, event, robot))

    def __call__(self, node: Node, old: State, new: State) -> None:
        if not isinstance(node, Capability):
            return
        key = id(node)
        if new is State.UNASSIGNED:
            holder = self._holder.pop(key, None)
            if holder is not None:
                self._lost[key] = holder
        elif new in (State.ASSIGNED, State.RUNNING):
            ex = node.execution
            if ex is not None:
                lost = self._lost.pop(key, None)
                if lost is not None and ex.robot != lost:
                    self.reassigned += 1
                self._holder[key] = ex.robot
        elif new is not State.PAUSED:  # the run ended (done, reset or shut down)
            self._holder.pop(key, None)
            self._lost.pop(key, None)


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
    log: MissionLog,
    errors: list[RobotError],
    started: float,
    ended: float,
    final: State,
    *,
    interrupted: bool = False,
) -> MissionResult:
    """Gather the result of a finished, timed-out or interrupted run."""
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
    mstats = operator.mission_control.stats
    return MissionResult(
        scenario=s.name,
        completed=final is State.SUCCEEDED and state.mission_complete,
        mission_time_s=round(duration, 3),
        summary={k: float(v) for k, v in state.summary().items()},
        robots=robots,
        auctions=operator.allocator.stats.auctions,
        executions_lost=operator.mission_control.stats.lost,
        reassigned=log.reassigned,
        robot_failures=log.applied["fail"],
        robots_left=log.applied["leave"],
        assignments=assignments,
        timeline=timeline,
        # Team changes only: "changed" (a member's capabilities changed) is no mark.
        marks=[
            Mark(round(t - started, 3), ev, robot) for t, ev, robot in log.marks if ev != "changed"
        ],
        moved=operator.mission_control.stats.moved,
        errors=[RobotError(round(e.time - started, 3), e.robot, e.error) for e in errors],
        timed_out=final not in DONE and not interrupted,
        interrupted=interrupted,
        exchanged=mstats.exchanged,
        undone=mstats.undone,
        held_back=mstats.held_back,
        foreseen_back=mstats.foreseen_back,
    )


def idle_robots_note(result: MissionResult, object_workers: int) -> str | None:
    """Why robots of a large team ran nothing, when the mission tree's parallelism may be
    the reason: it runs one Explore loop and ``object_workers`` identify-and-decontaminate
    loops, however many robots there are (``btcap run --robots N`` grows the team, not
    the tree). None when every robot ran something or the team is no larger than that."""
    at_once = 1 + object_workers
    idle = [r for r, st in result.robots.items() if not any(st.tasks.values())]
    if not idle or len(result.robots) <= at_once:
        return None
    names = ", ".join(idle[:6]) + (", ..." if len(idle) > 6 else "")
    loops = f"{object_workers} identify-and-decontaminate loop{'s' if object_workers > 1 else ''}"
    return (
        f"{result.scenario}: {len(idle)} of {len(result.robots)} robots ran no task "
        f"({names}): the mission tree runs one Explore loop and {loops} "
        f"(object_workers), at most {at_once} capabilities at once; --object-workers N "
        "runs more identify-and-decontaminate loops"
    )
