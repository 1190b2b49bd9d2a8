"""The pool mission's work lanes that hold one item each: a goal or an object's cell
(:class:`WorkLane`), a carrier standing by near an object (:class:`StandByLane`) and a
robot exploring while no object's work waits (:class:`SpareLane`); the object lanes
and pools are :mod:`btcap.sim.mission.pool`'s."""

from __future__ import annotations

from typing import Any, ClassVar

from btcap import Node, Port, Sequence, State

__all__ = ["SpareLane", "StandByLane", "WorkLane", "halt_all"]


class WorkLane(Sequence):
    """A Sequence for one work item ``(id, row, col)``, which it gives its children as
    outputs ``target`` and ``at`` before ticking them."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"item": tuple[int, int, int]}
    OUTPUTS: ClassVar[Any] = {"target": int, "at": tuple[int, int]}

    def on_tick(self) -> State:
        ident, row, col = self.inputs["item"][:3]
        self.outputs["target"] = int(ident)
        self.outputs["at"] = (int(row), int(col))
        return super().on_tick()


def halt_all(lane: Node) -> None:
    """Halt and reset ``lane``'s children: a capability reset frees its robot."""
    for c in lane.children:
        if c.state is not State.IDLE:
            c.reset()


class StandByLane(WorkLane):
    """A :class:`WorkLane` that stands a carrier by near an object awaiting
    identification, so that it is near if the object turns out contaminated: it ends
    (halting and resetting its children, which frees the robot) once the object is no
    longer ``listed`` awaiting identification (the object pool's ``plan``; a flag
    after the cell: 0), and fails (the same, but its object stays to stand by at again,
    with ``retry_failed``) while a carry waits for a robot (``waiting`` > 0: one being
    carried is no reason to stop). Ending there instead burnt through the plan in one
    tick: every object awaiting identification was marked done with, and no carrier
    stood by again (full-team-6 seed 3: a Husky idle 228-245 s)."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {
        "item": tuple[int, int, int],
        "listed": list[tuple[int, ...]],
        "waiting": Port(int, 0),
    }

    def on_tick(self) -> State:
        ident = self.inputs["item"][0]
        listed = self.inputs["listed"] or []
        wanted = any(i[0] == ident and not any(i[3:]) for i in listed)
        if wanted and not self.inputs["waiting"]:
            return super().on_tick()
        halt_all(self)
        return State.SUCCEEDED if not wanted else State.FAILED


class SpareLane(WorkLane):
    """A :class:`WorkLane` for a robot whose own pools have nothing for it now: it runs
    only while no object's work waits for a robot (``waiting``: an identification or a
    carry not yet taken; one under way is no reason to stop), and fails at once
    otherwise, halting and resetting its children (which frees the robot for that work),
    so the item runs again in another lane."""

    __slots__ = ()
    INPUTS: ClassVar[Any] = {"item": tuple[int, int, int], "waiting": Port(int, 0)}

    def on_tick(self) -> State:
        if not self.inputs["waiting"]:
            return super().on_tick()
        halt_all(self)
        return State.FAILED
