"""The pool mission: the paper's work, structured so no robot waits on the tree.

The paper's tree (:mod:`btcap.sim.mission.paper`) runs one Explore loop beside
``object_workers`` loops that each hold an object from its identification to the end of
its carry: an object waits for a loop while a loop waits for a Husky, and the Spot is
idle meanwhile. Here work comes from pools the shared store lists as it appears, each run
by a :class:`~btcap.bt.foreach.ParallelForEach`: exploration goals (a lane each, as many
at once as robots explore and do nothing scarcer), and objects found with work left, a
lane each (:class:`ObjectLane`: identify, then carry if contaminated), so identification
never waits on exploration or on a carry. The carry is auctioned in the tick the
identification ends: the robot that identified the object, if it can carry, is then the
nearest bidder, before other work takes it. Identifications take turns (as many at once
as robots identify and do nothing scarcer), so a carrier is not handed one a Spot will
do, along one plan (:mod:`~btcap.sim.mission.idplan`: nearest first from where each
identifier is); a carrier with nothing else to do stands by where that plan sends the
identifiers (:class:`StandByLane`), and robots that explore and can also do object work explore
while no object's work waits for a robot (:class:`SpareLane`).

A lane that fails leaves its item listed (the store still has it to do) and the item
runs again; a goal that another exploration covered leaves the list. Items are told
apart by id: an object dropped by a failing robot keeps its lane (re-assigned with the
capability), which is told where the object now lies; a failed carry runs again only
from a list read after its object fell.
"""

from __future__ import annotations

from collections.abc import Hashable
from collections.abc import Sequence as Seq
from typing import Any, ClassVar

from btcap import Node, Parallel, ParallelForEach, Port, State, Tree
from btcap.actors import ActorError
from btcap.sim.mission.capabilities import (
    DECONTAMINATE,
    EXPLORE,
    IDENTIFY,
    SPARE_EXPLORE,
    STANDBY,
)
from btcap.sim.mission.carryplan import CarryPace, CarryTurns, carry_metres
from btcap.sim.mission.goals import GoalPool
from btcap.sim.mission.idplan import Pace, Turns
from btcap.sim.mission.lanes import ObjectLane, SpareLane, StandByLane, WorkLane
from btcap.sim.mission.leaves import ClaimWork
from btcap.sim.world.distance import Cell
from btcap.sim.world.grid import GridMap
from btcap.sim.world.messages import ListWork, WorkList
from btcap.sim.world.model import RobotModel

__all__ = [
    "ObjectLane",
    "ObjectPool",
    "SpareLane",
    "StandByLane",
    "WatchWork",
    "WorkLane",
    "pool_lanes",
    "pool_mission_tree",
    "spare_explorers",
    "standby_lanes",
]

_KINDS = ("goal", "identify", "carry", "object")
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)
_NOT_BEGUN = (State.IDLE, State.UNASSIGNED)  # no robot has it yet
_OPS = ("explore", "identify", "decontaminate")


def pool_lanes(models: Seq[RobotModel]) -> tuple[int, int, int]:
    """Lanes for (explore, identify, carry): as many as robots that can do the work and
    nothing scarcer (fewer robots can do it), or if there are none, every robot able.

    A robot that alone can do scarce work (a Husky carrying) is then not handed work
    other robots can do merely because a lane for it was waiting; it still takes such
    work when it is the best for it (lanes are not robots: the auction decides who).
    """
    able = {k: [m for m in models if m.can(k)] for k in _OPS}
    out = []
    for k in _OPS:
        scarcer = [j for j in _OPS if j != k and len(able[j]) < len(able[k])]
        own = [m for m in able[k] if not any(m.can(j) for j in scarcer)]
        out.append(max(1, len(own) or len(able[k])))
    return out[0], out[1], out[2]


def spare_explorers(models: Seq[RobotModel]) -> int:
    """Explore lanes beyond :func:`pool_lanes`' own: one for every other robot able to
    explore, run only while nothing waits to be identified or carried (a Husky explores
    before anything is found, then goes to the work only it and its like can do)."""
    return sum(m.can("explore") for m in models) - pool_lanes(models)[0]


def standby_lanes(models: Seq[RobotModel]) -> int:
    """Robots that stand by near objects awaiting identification: those that can carry
    and get no lane of another pool (:func:`pool_lanes`: a Husky beside a Spot and a
    Bebop); none where the carriers also identify or explore (they have work to do)."""
    able = {k: [m for m in models if m.can(k)] for k in _OPS}
    others = set()
    for k in ("explore", "identify"):
        scarcer = [j for j in _OPS if j != k and len(able[j]) < len(able[k])]
        own = [m for m in able[k] if not any(m.can(j) for j in scarcer)] or able[k]
        others |= {id(m) for m in own}
    return sum(id(m) not in others for m in able["decontaminate"])


class WatchWork(ClaimWork):
    """Lists the work of ``kind`` waiting in the store, asking again every ``poll_s``:
    RUNNING while more may come or some is left, SUCCEEDED once none is left nor can
    come. (It lists on after the list is complete: a list left as it was then would keep
    offering work done since, which a lane would try again and again.) ``listed_at`` is
    the clock time the list was asked for: work ended before it is off the list."""

    __slots__ = ("_asked",)
    OUTPUTS: ClassVar[Any] = {
        "items": list[tuple[int, ...]],
        "complete": bool,
        "listed_at": float,
    }
    OPTIONS: ClassVar[Any] = {
        "kind": Port(str, description="goal, identify, carry or object"),
        "store": Port(str, "sim/store"),
        "poll_s": Port(float, 0.5, "clock seconds between two lists"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._asked = 0.0
        super().__init__(*args, **kwargs)

    def declare_ports(self) -> None:
        if self.options["kind"] not in _KINDS:
            raise ValueError(f"{self.name!r}: kind must be one of {', '.join(_KINDS)}")

    def on_tick(self) -> State:
        if self._task is None and self.clock.now() < self._again_at:
            return State.RUNNING
        if self._task is None:
            self._asked = self.clock.now()
        reply = self._poll(self._list)
        if reply is None:
            return State.RUNNING
        self._answer = None
        self._again_at = self.clock.now() + self.options["poll_s"]
        self.outputs["items"] = [tuple(i) for i in reply.items]
        self.outputs["complete"] = reply.complete
        self.outputs["listed_at"] = self._asked
        return State.SUCCEEDED if reply.complete and not reply.items else State.RUNNING

    async def _list(self) -> WorkList:
        try:
            reply: WorkList = await self._ref_to(self.options["store"]).ask(
                ListWork(self.options["kind"]), expect=WorkList, timeout=5.0
            )
        except ActorError:
            return WorkList([], False)
        return reply


class ObjectPool(ParallelForEach):
    """The :class:`ObjectLane` of every object with work left; beside the counts of
    :class:`~btcap.bt.foreach.ParallelForEach` it says how much work waits for a robot:
    ``waiting`` (objects listed without a lane, lanes whose capability is unassigned)
    and ``carries_waiting`` (those of them to carry), so robots that only stand by or
    explore meanwhile know when they are wanted; and ``plan``: the objects awaiting
    identification in the order they will be identified (under way first, then as
    :mod:`~btcap.sim.mission.idplan` routes the identifiers), where carriers stand by;
    with ``identify_at_once``, the next to start is the first planned for a free one.
    With ``carriers`` (robots that only carry) and a ``carry_pace`` and ``grid`` to price
    carries on, the carries waiting are offered as :mod:`~btcap.sim.mission.carryplan`
    says (those it starts on a carrier free now), not all at once."""

    __slots__ = ("_carries", "_offer", "_turns")
    OUTPUTS: ClassVar[Any] = {
        **ParallelForEach.OUTPUTS,
        "waiting": int,
        "carries_waiting": int,
        "plan": list[tuple[int, ...]],
    }
    OPTIONS: ClassVar[Any] = {
        **ParallelForEach.OPTIONS,
        "identify_at_once": Port(
            int, 0, "identifications at once (the rest wait for one to end); 0: no limit"
        ),
        "identify_wait_s": Port(float, 240.0, "an object waiting this long goes before nearer"),
        "identify_speed": Port(float, 1.0, "cells per second an identifier drives"),
        "identify_s": Port(float, 0.0, "seconds an identification takes"),
        "identify_carries": Port(bool, False, "identifiers carry: held for a carry auctioned"),
        "carriers": Port(int, 0, "robots that only carry (0: every carry offered at once)"),
    }

    def __init__(
        self,
        *args: Any,
        grid: GridMap | None = None,
        carry_pace: CarryPace | None = None,
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        self._turns = Turns()
        n = self.options["carriers"]
        self._carries: CarryTurns | None = None
        if n > 0 and grid is not None and carry_pace is not None:
            self._carries = CarryTurns(n, carry_pace, carry_metres(grid))
        self._offer: tuple[set[Hashable], set[Hashable]] = (set(), set())  # planned, offered

    def _run(self, i: int, item: Any) -> State:
        lane = self.children[i]
        if isinstance(lane, ObjectLane):
            planned, offered = self._offer
            lane.may_carry = item[0] not in planned or item[0] in offered
        most = self.options["identify_at_once"]
        if most <= 0 or not isinstance(lane, ObjectLane):
            return super()._run(i, item)
        identify = lane.children[0]
        if identify.state is State.IDLE:
            lanes = [c for k, c in zip(self._lanes, self.children, strict=True) if k is not None]
            under_way = sum(c is not lane and c.children[0].state in _ACTIVE for c in lanes)
            lane.may_identify = under_way < most and self._turns.may_start(item[0], self._plan())
        was = identify.state
        state = super()._run(i, item)
        if was is State.IDLE and identify.state is not State.IDLE:
            self._turns.started(item[0], (int(item[1]), int(item[2])), self._plan())
        elif was in _ACTIVE and not self._identifying(lane):
            self._turns.free(item[0])
        return state

    def _identifying(self, lane: Node) -> bool:
        """Its identifier is not free: identifying, or to carry what it found (Pace)."""
        identify, carry = lane.children
        held = self.options["identify_carries"] and carry.state is State.UNASSIGNED
        return identify.state in _ACTIVE or (held and identify.state is State.SUCCEEDED)

    def _plan(self) -> list[tuple[Hashable, int]]:
        """The plan of the objects awaiting a turn in a lane, or to run again soon."""
        lanes = zip(self._values, self.children, strict=True)
        values = [v for v, c in lanes if v is not None and c.children[0].state is State.IDLE]
        values += [it for it in self.inputs["items"] or [] if it[0] in self._retry_at]
        awaiting = [(v[0], (int(v[1]), int(v[2]))) for v in values if not v[3]]
        o = self.options
        pace = Pace(o["identify_speed"], o["identify_s"], o["identify_wait_s"])
        return self._turns.plan(o["identify_at_once"], awaiting, self.clock.now(), pace)

    def on_tick(self) -> State:
        items = self.inputs["items"] or []
        self._turns.listed([it[0] for it in items if not it[3]], self.clock.now())
        self._offer = self._carry_offer(items)
        state = super().on_tick()
        waiting = carries = 0
        under_way, known = set(), set()
        for i, lane in enumerate(self.children):
            if self._lanes[i] is None or lane.state not in _ACTIVE:
                continue
            identify, carry = lane.children
            if self._identifying(lane):
                under_way.add(self._lanes[i])
            elif identify.state is State.SUCCEEDED:
                known.add(self._lanes[i])
            if carry.state is State.UNASSIGNED:
                waiting, carries = waiting + 1, carries + 1
            elif carry.state is State.IDLE and identify.state in _NOT_BEGUN:
                waiting += 1
        self._turns.ended(under_way)  # also lanes that failed or were reset
        held = set(self._lanes)
        for item in items:
            if item[0] not in held and self._unstarted(item[0]):
                waiting += 1
                carries += bool(item[3])
        self.outputs["waiting"], self.outputs["carries_waiting"] = waiting, carries
        # where carriers stand by: under way, planned, then those in no lane yet
        at = {it[0]: (int(it[0]), int(it[1]), int(it[2])) for it in items if not it[3]}
        first = self._turns.order(self._plan() if self.options["identify_at_once"] else [])
        skip = set(first) | known | self._finished | self._lost
        plan = [at[k] for k in first if k in at] + [v for k, v in at.items() if k not in skip]
        self.outputs["plan"] = plan
        return state

    def _carry_offer(self, items: list[tuple[int, ...]]) -> tuple[set[Hashable], set[Hashable]]:
        """The carries planned and, of them, those offered now (:class:`CarryTurns`); a
        carry not planned (its identification ends in this tick) is offered at once."""
        if self._carries is None:
            return set(), set()
        waiting: dict[Hashable, Cell] = {}
        under_way: dict[Hashable, Cell] = {}
        for k, v, lane in zip(self._lanes, self._values, self.children, strict=True):
            if k is None or v is None:
                continue
            if not v[3] and lane.children[0].state is not State.SUCCEEDED:
                continue  # not known contaminated yet
            carry = lane.children[1].state
            if carry is State.RUNNING or carry is State.ASSIGNED:
                under_way[k] = (int(v[1]), int(v[2]))
            elif carry in _NOT_BEGUN:
                waiting[k] = (int(v[1]), int(v[2]))
        for it in items:  # known contaminated, in no lane yet
            if it[3] and it[0] not in self._lanes and self._unstarted(it[0]):
                waiting[it[0]] = (int(it[1]), int(it[2]))
        offered = self._carries.offer(self.clock.now(), waiting, under_way)
        return set(waiting), offered

    def _unstarted(self, key: int) -> bool:
        return key not in self._finished and key not in self._lost

    def on_reset(self) -> None:
        super().on_reset()
        self._turns = Turns()
        if self._carries is not None:
            self._carries.forget()
        self._offer = (set(), set())


def pool_mission_tree(
    *,
    explorers: int = 1,
    identifiers: int = 1,
    carriers: int = 1,
    standby: int = 0,
    spare_explorers: int = 0,
    objects: int = 0,
    store: str = "sim/store",
    grid: GridMap | None = None,
    near_m: float = 0.0,
    pace: Pace | None = None,
    carry_pace: CarryPace | None = None,
) -> Tree:
    """The pool mission with at most ``explorers`` explorations at once (and
    ``spare_explorers`` more while no object's work waits), an object lane for each of
    up to ``objects`` objects with work left at once (at least ``identifiers +
    carriers``: the lanes only hold work, robots are the auction's), and ``standby``
    carriers standing by near objects awaiting identification while no carry waits
    (where the identifiers go next: ``pace`` prices their plan, :mod:`.idplan`; while
    carries wait for them, ``carry_pace`` prices the carries' plan, :mod:`.carryplan`); it
    succeeds once the cave is explored and every object found is identified and, if
    contaminated, carried. A free explore lane takes the goal nearest (by path on
    ``grid``) to where its last goal left its explorer, those within ``near_m`` of a goal
    being explored last (:class:`~btcap.sim.mission.goals.GoalPool`)."""
    for kind, lanes in (("goal", explorers), ("identify", identifiers), ("carry", carriers)):
        if lanes < 1:
            raise ValueError(f"{kind}: expected at least one lane, got {lanes}")
    parts: list[Node] = []
    wires: list[tuple[Node, str, Node, str]] = []
    # objects: a lane each, identify then carry
    watch_objects = WatchWork("list_object", kind="object", store=store)
    n_objects = max(objects, identifiers + carriers)
    object_lanes: list[Node] = []
    for k in range(n_objects):
        identify = IDENTIFY.node_type()("identify")
        carry = DECONTAMINATE.node_type()("decontaminate")
        lane = ObjectLane(f"object_{k + 1}", children=[identify, carry])
        object_lanes.append(lane)
        wires += [
            (lane, "target", identify, "object"),
            (lane, "at", identify, "at"),
            (lane, "target", carry, "object"),
            (lane, "at", carry, "at"),
        ]
    # Items told apart by their id: an object dropped elsewhere is the same object, its
    # running lane told where it now lies, not a second lane started for it. A failed
    # carry dropped its object where the carrier was: it runs again from a list read
    # after the drop (a poll begun after it has come back within four poll periods).
    each_object = ObjectPool(
        "each_object",
        children=object_lanes,
        retry_failed=True,
        key=0,
        retry_after_s=4 * watch_objects.options["poll_s"],
        identify_at_once=identifiers,
        carriers=standby,
        grid=grid,
        carry_pace=carry_pace,
        **(pace or Pace()).options(),
    )
    wires += [
        (watch_objects, "items", each_object, "items"),
        (watch_objects, "complete", each_object, "complete"),
    ]
    parts.append(Parallel("object_pool", children=[watch_objects, each_object]))
    # goals: the explore lanes, then the spare ones
    watch_goals = WatchWork("list_goal", kind="goal", store=store)
    caps = [EXPLORE.node_type()("explore") for _ in range(explorers)]
    caps += [SPARE_EXPLORE.node_type()("explore_meanwhile") for _ in range(spare_explorers)]
    goal_lanes: list[WorkLane] = [
        WorkLane(f"goal_{k + 1}", children=[cap]) for k, cap in enumerate(caps[:explorers])
    ]
    goal_lanes += [
        SpareLane(f"spare_goal_{k + 1}", children=[c]) for k, c in enumerate(caps[explorers:])
    ]
    each_goal = GoalPool(
        "each_goal", children=goal_lanes, retry_failed=True, key=0, grid=grid, near_m=near_m
    )
    for ln, cap in zip(goal_lanes, caps, strict=True):
        wires.append((ln, "at", cap, "goal"))
        if isinstance(ln, SpareLane):
            wires.append((each_object, "waiting", ln, "waiting"))
    wires += [
        (watch_goals, "items", each_goal, "items"),
        (watch_goals, "complete", each_goal, "complete"),
        (watch_goals, "listed_at", each_goal, "listed_at"),
    ]
    parts.append(Parallel("goal_pool", children=[watch_goals, each_goal]))
    if standby > 0:  # at the objects identified next: the identifiers' plan
        bys = [STANDBY.node_type()("standby") for _ in range(standby)]
        stand = [StandByLane(f"standby_{k + 1}", children=[c]) for k, c in enumerate(bys)]
        each = ParallelForEach("each_standby", children=stand, key=0, retry_failed=True)
        for ln, cap in zip(stand, bys, strict=True):
            wires += [
                (ln, "at", cap, "at"),
                (each_object, "plan", ln, "listed"),
                (each_object, "carries_waiting", ln, "waiting"),
            ]
        wires += [
            (each_object, "plan", each, "items"),
            (watch_objects, "complete", each, "complete"),
        ]
        parts.append(each)
    tree = Tree(Parallel("mission", children=parts), name="find_and_decontaminate_pool")
    for src, out, dst, inp in wires:
        tree.wire(src, out, dst, inp)
    return tree
