"""Messages between robots and the simulation manager / shared object store."""

from __future__ import annotations

from btcap.transports.message import Message

__all__ = [
    "SIM_MESSAGES",
    "Claim",
    "ClaimReply",
    "ListWork",
    "MoveTo",
    "Operate",
    "PositionUpdate",
    "SimResult",
    "StopRobot",
    "WorkList",
]


class MoveTo(Message):
    """Drive ``robot`` to ``goal`` (row, col); answered when it arrives or cannot."""

    robot: str
    goal: tuple[int, int]


class StopRobot(Message):
    """Stop ``robot`` where it is (its move was abandoned)."""

    robot: str


class Operate(Message):
    """Run a sim operation: ``explore`` at the robot's cell, ``identify`` or
    ``decontaminate`` object ``target``; answered after its (randomised) duration."""

    robot: str
    op: str
    target: int = -1


class SimResult(Message):
    """How a move or operation ended, and where the robot is now."""

    ok: bool
    position: tuple[int, int]
    detail: str = ""
    found: int = 0
    contaminated: bool | None = None


class PositionUpdate(Message):
    """The robot's body as the simulation has it now: sent on every cell it drives into,
    when a move ends or stops, and when an operation starts, begins its timed work or ends.

    ``op`` is the operation under way or just done ("" if none) on object ``target`` (-1:
    none, as for explore), in ``phase`` ``carry`` (decontaminate first carries the object to
    the decontamination area), ``work`` (its timed work has begun) or ``done`` (it ended
    well; a failed one leaves no operation). With it the robot's bids for the work it
    holds say what finishing costs *now*, not from where it started.
    """

    robot: str
    position: tuple[int, int]
    op: str = ""
    target: int = -1
    phase: str = ""


class Claim(Message):
    """Ask the store for work: ``kind`` is ``goal`` or ``object``; one claim per claimant."""

    claimant: str
    kind: str


class ClaimReply(Message):
    """``status``: ``ok`` (work in ``target``/``at``), ``wait`` (nothing yet), ``done``."""

    status: str
    target: int = -1
    at: tuple[int, int] = (0, 0)
    identified: bool = False


class ListWork(Message):
    """Ask the store what work waits: ``kind`` is ``goal``, ``identify``, ``carry`` or
    ``object`` (see :meth:`~btcap.sim.world.store.MissionState.work_list`)."""

    kind: str


class WorkList(Message):
    """The work of a kind, each ``(id, row, col)`` (``object``: and a flag); ``complete``:
    no more will come."""

    items: list[tuple[int, ...]]
    complete: bool


SIM_MESSAGES: tuple[type[Message], ...] = (
    MoveTo,
    StopRobot,
    Operate,
    SimResult,
    PositionUpdate,
    Claim,
    ClaimReply,
    ListWork,
    WorkList,
)
