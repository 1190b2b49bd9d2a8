"""The simulated world as monitor events: the map once, then what changed.

A monitor samples :meth:`WorldFeed.sample` at every batch (every simulation step on a
virtual clock), so a recording holds what every robot was doing and what became of every
object step by step, and the same bytes in every ``--fast`` run of a seed. Each part
(poses, robots' state and task, objects) holds only the robots or objects that changed
since it was last sent, and is left out when none did: robots that stand still and
objects nobody touched cost nothing (the first event holds every one; a reader adds each
event to what it had, as :class:`btcap.monitor.scene.Scene` does). Poses, the bulk of a
recording (robots drive most of a mission), are sent at most once per ``pose_every_s``
clock seconds (:data:`POSE_EVERY_S`), and at once with a change of a robot's state or
task or of an object, and by :meth:`WorldFeed.last` at the end: a robot then hops a few
cells at a time in Foxglove (which draws the latest pose, it interpolates nothing), but
stands where it was whenever it starts or ends a task. The events' shapes and how Foxglove
draws them are in :mod:`btcap.monitor.scene`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from operator import attrgetter
from typing import Any

import numpy as np

from btcap.monitor.view import Event
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.store import SimObject

__all__ = ["POSE_EVERY_S", "WorldFeed"]

#: Clock seconds between two poses of the robots at most (four simulator steps): a
#: recording of a drive then costs a quarter of its messages (see the module's doc).
POSE_EVERY_S = 2.0

#: What of an object the world's picture shows (its key: compared at every batch).
_OBJECT_KEY = attrgetter("found", "identified", "decontaminated", "carried_by", "cell")


class WorldFeed:
    """Reads the simulation's ground truth (a :class:`SimulationManager`'s) for a monitor."""

    def __init__(
        self,
        manager: SimulationManager,
        *,
        pose_every_s: float | None = None,
        absent: Iterable[str] = (),
    ) -> None:
        if pose_every_s is None:
            pose_every_s = POSE_EVERY_S
        if not pose_every_s >= 0:
            raise ValueError(f"pose_every_s {pose_every_s}: expected clock seconds >= 0")
        self.manager = manager
        self.pose_every_s = pose_every_s
        self._pose_t = -math.inf  # clock time of the last poses sent
        grid = manager.state.grid
        self._cell = grid.cell_size_m
        self._height = grid.height
        # what each part was last sent for (see :meth:`sample`); None: never sent
        self._robots: list[tuple[bool, int]] | None = None
        self._objects: list[tuple[Any, ...]] | None = None
        self._changes = -1  # the state's count of object changes when last compared
        self._poses: bytes | None = None
        self._cells: dict[str, list[int]] = {}  # each robot's cell as its pose was last sent
        #: Robots not in the team yet (a scenario's later joiners): the simulation has them
        #: idle at the start, up, from the first step; the picture leaves them out until
        #: :meth:`joined`, as the team does.
        self._absent = set(absent)

    def joined(self, robot: str) -> None:
        """``robot`` joined the team: the next sample has its state, task and pose."""
        if robot not in self._absent:
            return
        self._absent.discard(robot)
        if self._robots is not None:  # its key as never sent: compared, it differs
            self._robots[list(self.manager.robots).index(robot)] = (False, -1)
        self._poses = None  # the cells are compared again, and its cell was never sent

    def _xy(self, row: int, col: int) -> list[float]:
        """A cell's centre in the ``map`` frame (x along columns, y up from the last row)."""
        c = self._cell
        return [(col + 0.5) * c, (self._height - row - 0.5) * c]

    def map_event(self, t: float) -> Event:
        """The map, its start and its decontamination area (``map``)."""
        grid = self.manager.state.grid
        chars = np.where(grid.free, np.where(grid.reachable, ".", ":"), "#")
        return {
            "t": t,
            "k": "map",
            "rows": ["".join(row) for row in chars.tolist()],
            "cell_m": self._cell,
            "start": self._xy(*grid.start),
            "decon": self._xy(*grid.decon_area),
        }

    def sample(self) -> Event | None:
        """The parts of the world that changed since the last sample (``world``), or None;
        poses at most once per :attr:`pose_every_s` unless another part changed too.
        Each part is compared by a cheap key first (the step's cells as bytes, the robots'
        operations, the objects' fields once the state counts a change of any) and only
        built when that changed."""
        return self._sample(final=False)

    def last(self) -> Event | None:
        """:meth:`sample` once more at the end, poses whatever their rate, and every
        robot's state and task: the final picture is exact, and a timeline of each
        robot's task (Foxglove's State Transitions panel) runs to the end."""
        return self._sample(final=True)

    def _sample(self, *, final: bool) -> Event | None:
        m = self.manager
        now = m.now()
        ev: Event | None = None
        # keys built in C where it can (a batch mostly finds nothing changed: issue 32)
        robots = [
            (r.up, id(r.busy[-1].event) if r.busy else id(r.move_event)) for r in m.robots.values()
        ]
        if robots != self._robots or final:  # at the end every robot: lanes run to it
            last, self._robots = self._robots, robots
            changed = self._changed_robots(robots, None if final else last)
            if changed or final:  # none: only robots not in the team yet changed
                ev = {"t": now, "k": "world", "robots": changed}
        changes = m.state.changes  # objects change through the state's methods only
        if changes != self._changes:
            self._changes = changes
            objects = list(map(_OBJECT_KEY, m.state.objects))
            if objects != self._objects:
                last_objects, self._objects = self._objects, objects
                if ev is None:
                    ev = {"t": now, "k": "world"}
                was = last_objects or []
                ev["objects"] = [
                    self._object(o)
                    for i, (o, key) in enumerate(zip(m.state.objects, objects, strict=True))
                    if i >= len(was) or key != was[i]
                ]
        if final or ev is not None or now >= self._pose_t + self.pose_every_s:
            where = m.cells.tobytes()
            if self._poses != where:
                self._poses = where
                moved = self._moved()
                if moved:
                    self._pose_t = now
                    if ev is None:
                        ev = {"t": now, "k": "world"}
                    ev["poses"] = moved
        return ev

    def _changed_robots(
        self, keys: list[tuple[bool, int]], last: list[tuple[bool, int]] | None
    ) -> dict[str, dict[str, Any]]:
        """The robots whose key differs from ``last`` (all of them at first)."""
        absent = self._absent
        return {
            name: {"up": r.up, "task": _task(r.busy, r.move_event)}
            for i, (name, r) in enumerate(self.manager.robots.items())
            if (last is None or i >= len(last) or keys[i] != last[i]) and name not in absent
        }

    def _moved(self) -> dict[str, list[float]]:
        """The poses of the robots whose cell differs from the last poses sent."""
        m = self.manager
        cells = m.cells.tolist()
        sent = self._cells
        moved = {}
        absent = self._absent
        for name, r in m.robots.items():
            if name in absent:
                continue
            cell = cells[r.index]
            if sent.get(name) != cell:
                sent[name] = cell
                moved[name] = self._xy(*cell)
        return moved

    def _object(self, o: SimObject) -> dict[str, Any]:
        if o.decontaminated:
            status = "decontaminated"
        elif o.carried_by is not None:
            status = "carried"
        elif o.identified is not None:
            status = "contaminated" if o.identified else "clean"
        else:
            status = "found" if o.found else "hidden"
        x, y = self._xy(*o.cell)
        return {"id": o.id, "x": x, "y": y, "status": status, "by": o.carried_by}


def _task(busy: list[Any], move: Any) -> str:
    """What a robot is doing, as its simulation knows it."""
    if busy:
        op = busy[-1]
        return op.event.kind if op.target < 0 else f"{op.event.kind} object {op.target}"
    if move is not None:
        return f"move {move.detail}"
    return "idle"
