"""The pool mission's work lanes that hold one item each: a goal or an object's cell
(:class:`WorkLane`), all the work one object needs (:class:`ObjectLane`), a carrier
standing by near an object (:class:`StandByLane`) and a robot exploring while no
object's work waits (:class:`SpareLane`); the pools are :mod:`btcap.sim.mission.pool`'s."""

from __future__ import annotations

from typing import Any, ClassVar

from btcap import Node, Port, Sequence, State

__all__ = ["ObjectLane", "SpareLane", "StandByLane", "WorkLane", "halt_all"]

_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)
_NOT_BEGUN = (State.IDLE, State.UNASSIGNED)  # no robot has it yet


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


class ObjectLane(WorkLane):
    """All the work one object ``(id, row, col, contaminated)`` still needs: its first
    child identifies it (unless the item says it is known contaminated), its second
    carries it if contaminated, opened in the very tick the identification ends, so the
    robot that identified it (if it can carry) is the nearest bidder and is not taken by
    other work first; a clean object's lane succeeds there. A lane that fails (either
    step) runs again from the store's latest news of the object."""

    __slots__ = ("may_carry", "may_identify")
    INPUTS: ClassVar[Any] = {"item": tuple[int, int, int, int]}
    MIN_CHILDREN: ClassVar[int] = 2
    MAX_CHILDREN: ClassVar[int | None] = 2

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        #: Whether an identification may start now (its pool's limit; see ObjectPool).
        self.may_identify = True
        #: Whether its carry may be offered now (the pool's carry plan; see ObjectPool).
        self.may_carry = True

    def on_tick(self) -> State:
        ident, row, col, known = self.inputs["item"]
        self.outputs["target"] = int(ident)
        self.outputs["at"] = (int(row), int(col))
        identify, carry = self.children
        # An identification under way runs to its end even once the store knows the
        # result (the store hears it from the simulation before the capability reports):
        # left unticked, it would stay running and hold its turn for ever.
        started = identify.state in _ACTIVE
        if (not known or started) and identify.state is not State.SUCCEEDED:
            if identify.state is State.IDLE and not self.may_identify:
                return State.RUNNING  # its turn comes when an identification ends
            s = identify.tick()
            if s is State.FAILED or s is State.ERROR:
                return State.FAILED
            if s is not State.SUCCEEDED:
                return State.RUNNING
            if not identify.outputs["contaminated"]:
                return State.SUCCEEDED
        if carry.state in _NOT_BEGUN and not self.may_carry:
            if carry.state is not State.IDLE:
                carry.reset()  # its auction is called off: no robot has it yet
            return State.RUNNING  # another carry goes first
        s = carry.tick()
        if s is State.SUCCEEDED:
            return s
        return State.FAILED if s is State.FAILED or s is State.ERROR else State.RUNNING


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
