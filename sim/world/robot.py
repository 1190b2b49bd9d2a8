"""A simulated robot's own view of itself: where it is and what it does, as the
simulation last said (it says so on every cell and every change of operation)."""

from __future__ import annotations

from btcap.actors import Actor, handler
from btcap.sim.world.distance import Cell
from btcap.sim.world.messages import PositionUpdate

__all__ = ["Body"]


class Body(Actor):
    """Tracks the robot's cell and its operation, for bids: what finishing the work it
    holds would cost is priced from here and now (see :meth:`left_s`)."""

    PATH = "body"

    def __init__(self, robot: str, position: Cell) -> None:
        super().__init__()
        self.robot = robot
        self.position: Cell = position
        #: The operation under way or just done ("" if none), its object (-1: none, as
        #: for explore) and its phase: carry, work or done (see PositionUpdate).
        self.op = ""
        self.target = -1
        self.phase = ""
        self._work_since = 0.0  # clock time its timed work began
        #: The run it drives for, (op, target, goal), and the cell that run ends on; told
        #: by the run's own tree as it starts, forgotten when it stops.
        self.heading: tuple[tuple[str, int, Cell], Cell] | None = None

    def _now(self) -> float:
        return self._system.clock.now() if self._system is not None else 0.0

    @handler
    def on_position(self, msg: PositionUpdate) -> None:
        if msg.robot != self.robot:
            return
        self.position = (int(msg.position[0]), int(msg.position[1]))
        same = (msg.op, msg.target) == (self.op, self.target)
        if msg.phase == "work" and not (same and self.phase == "work"):
            self._work_since = self._now()
        self.op, self.target, self.phase = msg.op, msg.target, msg.phase

    def bound_for(self, decon_area: Cell, task: tuple[str, int, Cell]) -> Cell:
        """Where the work the robot holds leaves it, to price ``task`` (op, target, goal)
        after that work: the decontamination area while it carries an object there (or
        works at it), the end of the run it drives for (``heading``), else where it is
        (and for that very run: its own bid is what finishing costs from here)."""
        if self.op == "decontaminate" and self.phase in ("carry", "work"):
            return decon_area
        h = self.heading
        if h is not None and h[0] != task:
            return h[1]
        return self.position

    def left_s(self, op: str, target: int, duration_s: float) -> float | None:
        """Clock seconds of work left on ``op`` on ``target`` if it takes ``duration_s``:
        None if it is not under way (not begun, or a drive to it is all there is so far),
        ``duration_s`` while the object is carried, 0 once done (or overdue)."""
        if self.op != op or self.target != target or not self.phase:
            return None
        if self.phase == "carry":
            return duration_s
        if self.phase == "done":
            return 0.0
        return max(0.0, duration_s - (self._now() - self._work_since))
