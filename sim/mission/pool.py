"""The pool mission: the paper's work, structured so no robot waits on the tree.

The paper's tree (:mod:`btcap.sim.mission.paper`) runs one Explore loop beside
``object_workers`` loops that each hold an object from its identification to the end of
its carry: an object waits for a loop while a loop waits for a Husky, and the Spot is
idle meanwhile. Here each kind of work is a pool: exploration goals, objects found and
not yet identified, and objects found contaminated, each listed by the shared store as
it appears, and a :class:`~btcap.bt.foreach.ParallelForEach` runs a lane (one
capability) per item, with as many lanes as the scenario has robots able to do it. An
object is released to the carry pool the moment it is identified, and identification
never waits on exploration or on a carry. Robots the lanes leave out are not idle: a
carrier with nothing else to do stands by at the objects awaiting identification
(:class:`StandByLane`), and other explorers explore while nothing waits to be
identified or carried (:class:`SpareLane`).

A lane that fails leaves its item listed (the store still has it to do) and the item
runs again; a goal that another exploration covered leaves the list. Items are told
apart by id: an object dropped by a failing robot keeps its lane (re-assigned with the
capability), which is told where the object now lies; a failed carry runs again only
from a list read after its object fell.
"""

from __future__ import annotations

from collections.abc import Sequence as Seq
from typing import Any, ClassVar

from btcap import Node, Parallel, ParallelForEach, Port, Sequence, State, Tree
from btcap.actors import ActorError
from btcap.sim.mission.capabilities import DECONTAMINATE, EXPLORE, IDENTIFY, STANDBY
from btcap.sim.mission.leaves import ClaimWork
from btcap.sim.world.messages import ListWork, WorkList
from btcap.sim.world.model import RobotModel

__all__ = [
    "StandByLane",
    "WatchWork",
    "WorkLane",
    "pool_lanes",
    "pool_mission_tree",
    "standby_lanes",
]

_KINDS = ("goal", "identify", "carry")
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
    offering work done since, which a lane would try again and again.)"""

    __slots__ = ()
    OUTPUTS: ClassVar[Any] = {"items": list[tuple[int, int, int]], "complete": bool}
    OPTIONS: ClassVar[Any] = {
        "kind": Port(str, description="goal, identify or carry"),
        "store": Port(str, "sim/store"),
        "poll_s": Port(float, 0.5, "clock seconds between two lists"),
    }

    def declare_ports(self) -> None:
        if self.options["kind"] not in _KINDS:
            raise ValueError(f"{self.name!r}: kind must be one of {', '.join(_KINDS)}")

    def on_tick(self) -> State:
        if self._task is None and self.clock.now() < self._again_at:
            return State.RUNNING
        reply = self._poll(self._list)
        if reply is None:
            return State.RUNNING
        self._answer = None
        self._again_at = self.clock.now() + self.options["poll_s"]
        self.outputs["items"] = [tuple(i) for i in reply.items]
        self.outputs["complete"] = reply.complete
        return State.SUCCEEDED if reply.complete and not reply.items else State.RUNNING

    async def _list(self) -> WorkList:
        try:
            reply: WorkList = await self._ref_to(self.options["store"]).ask(
                ListWork(self.options["kind"]), expect=WorkList, timeout=5.0
            )
        except ActorError:
            return WorkList([], False)
        return reply


class WorkLane(Sequence):
    """A Sequence for one work item ``(id, row, col)``, which it gives its children as
    outputs ``target`` and ``at`` before ticking them."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"item": tuple[int, int, int]}
    OUTPUTS: ClassVar[Any] = {"target": int, "at": tuple[int, int]}

    def on_tick(self) -> State:
        ident, row, col = self.inputs["item"]
        self.outputs["target"] = int(ident)
        self.outputs["at"] = (int(row), int(col))
        return super().on_tick()


class StandByLane(WorkLane):
    """A :class:`WorkLane` that stands a carrier by near an object awaiting
    identification, so that it is near if the object turns out contaminated: it ends
    (halting and resetting its children, which frees the robot) once the object is no
    longer ``listed`` for identification or any carry waits (``carries``)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {
        "item": tuple[int, int, int],
        "listed": list[tuple[int, int, int]],
        "carries": list[tuple[int, int, int]],
    }

    def on_tick(self) -> State:
        ident = self.inputs["item"][0]
        wanted = any(i[0] == ident for i in self.inputs["listed"] or [])
        if wanted and not self.inputs["carries"]:
            return super().on_tick()
        for c in self.children:
            if c.state is not State.IDLE:
                c.reset()
        return State.SUCCEEDED


class SpareLane(WorkLane):
    """A :class:`WorkLane` for a robot whose own pools have nothing for it now: it runs
    only while no object waits to be identified or carried (``identify``, ``carry``),
    and fails at once otherwise, halting and resetting its children (which frees the
    robot for that work), so the item runs again in another lane."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {
        "item": tuple[int, int, int],
        "identify": list[tuple[int, int, int]],
        "carry": list[tuple[int, int, int]],
    }

    def on_tick(self) -> State:
        if not self.inputs["identify"] and not self.inputs["carry"]:
            return super().on_tick()
        for c in self.children:
            if c.state is not State.IDLE:
                c.reset()
        return State.FAILED


def pool_mission_tree(
    *,
    explorers: int = 1,
    identifiers: int = 1,
    carriers: int = 1,
    standby: int = 0,
    spare_explorers: int = 0,
    store: str = "sim/store",
) -> Tree:
    """The pool mission with at most ``explorers`` explorations, ``identifiers``
    identifications and ``carriers`` carries at once, and ``standby`` carriers standing
    by near objects awaiting identification while no carry waits; it succeeds once the
    cave is explored and every object found is identified and, if contaminated, carried."""
    parts: list[Node] = []
    wires: list[tuple[Node, str, Node, str]] = []
    watches: dict[str, WatchWork] = {}
    spares: list[Node] = []
    for kind, interface, lanes in (
        ("goal", EXPLORE, explorers),
        ("identify", IDENTIFY, identifiers),
        ("carry", DECONTAMINATE, carriers),
    ):
        if lanes < 1:
            raise ValueError(f"{kind}: expected at least one lane, got {lanes}")
        watch = watches[kind] = WatchWork(f"list_{kind}", kind=kind, store=store)
        spare = spare_explorers if kind == "goal" else 0
        caps = [interface.node_type()(interface.name.lower()) for _ in range(lanes + spare)]
        lane: list[WorkLane] = [
            WorkLane(f"{kind}_{k + 1}", children=[cap]) for k, cap in enumerate(caps[:lanes])
        ]
        lane += [
            SpareLane(f"spare_{kind}_{k + 1}", children=[c]) for k, c in enumerate(caps[lanes:])
        ]
        spares += lane[lanes:]
        # Items told apart by their id: an object dropped elsewhere is the same object,
        # its running lane told where it now lies, not a second lane started for it.
        # A failed carry dropped its object where the carrier was: it runs again from a
        # list read after the drop (a poll begun after it has come back within four poll
        # periods), not from the spot it was taken at.
        wait = 4 * watch.options["poll_s"] if kind == "carry" else 0.0
        each = ParallelForEach(
            f"each_{kind}", children=lane, retry_failed=True, key=0, retry_after_s=wait
        )
        for ln, cap in zip(lane, caps, strict=True):
            if kind == "goal":
                wires.append((ln, "at", cap, "goal"))
            else:
                wires += [(ln, "target", cap, "object"), (ln, "at", cap, "at")]
        parts.append(Parallel(f"{kind}_pool", children=[watch, each]))
        wires += [(watch, "items", each, "items"), (watch, "complete", each, "complete")]
    for spare_lane in spares:
        wires += [(watches[k], "items", spare_lane, k) for k in ("identify", "carry")]
    if standby > 0:
        bys = [STANDBY.node_type()("standby") for _ in range(standby)]
        stand = [StandByLane(f"standby_{k + 1}", children=[c]) for k, c in enumerate(bys)]
        each = ParallelForEach("each_standby", children=stand, key=0)
        for ln, cap in zip(stand, bys, strict=True):
            wires += [
                (ln, "at", cap, "at"),
                (watches["identify"], "items", ln, "listed"),
                (watches["carry"], "items", ln, "carries"),
            ]
        wires += [
            (watches["identify"], "items", each, "items"),
            (watches["identify"], "complete", each, "complete"),
        ]
        parts.append(each)
    tree = Tree(Parallel("mission", children=parts), name="find_and_decontaminate_pool")
    for src, out, dst, inp in wires:
        tree.wire(src, out, dst, inp)
    return tree
