"""The simulated world as monitor events: the map once, then what changed.

A monitor samples :meth:`WorldFeed.sample` at every batch (every simulation step on a
virtual clock), so a recording holds what every robot was doing and what became of every
object step by step, and the same bytes in every ``--fast`` run of a seed. Each part
(poses, robots' state and task, objects) is sent whole when it changed and not at all
otherwise: robots that stand still cost nothing. Poses, the bulk of a recording (robots
drive most of a mission), are sent at most once per ``pose_every_s`` clock seconds
(:data:`POSE_EVERY_S`), and at once with a change of a robot's state or task or of an
object, and by :meth:`WorldFeed.last` at the end: a robot then hops a few cells at a
time in Foxglove (which draws the latest pose, it interpolates nothing), but stands
where it was whenever it starts or ends a task. The events' shapes and how Foxglove
draws them are in :mod:`btcap.monitor.scene`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from btcap.monitor.view import Event
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.store import SimObject

__all__ = ["POSE_EVERY_S", "WorldFeed"]

#: Clock seconds between two poses of the robots at most (four simulator steps): a
#: recording of a drive then costs a quarter of its messages (see the module's doc).
POSE_EVERY_S = 2.0


class WorldFeed:
    """Reads the simulation's ground truth (a :class:`SimulationManager`'s) for a monitor."""

    def __init__(self, manager: SimulationManager, *, pose_every_s: float | None = None) -> None:
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
        self._keys: dict[str, Any] = {}

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
        operations, the objects' fields) and only built when that changed."""
        return self._sample(final=False)

    def last(self) -> Event | None:
        """:meth:`sample` once more at the end, poses whatever their rate: the final
        picture is exact."""
        return self._sample(final=True)

    def _sample(self, *, final: bool) -> Event | None:
        m = self.manager
        now = m.now()
        robots = m.robots.values()
        keys = {
            "robots": tuple(
                (r.up, id(r.busy[-1].event) if r.busy else id(r.move_event)) for r in robots
            ),
            "objects": tuple(
                (o.found, o.identified, o.decontaminated, o.carried_by, o.cell)
                for o in m.state.objects
            ),
        }
        ev: Event = {"t": now, "k": "world"}
        for part, key in keys.items():
            if self._keys.get(part) != key:
                self._keys[part] = key
                ev[part] = self._part(part)
        if final or len(ev) > 2 or now >= self._pose_t + self.pose_every_s:
            where = m.cells.tobytes()
            if self._keys.get("poses") != where:
                self._keys["poses"] = where
                self._pose_t = now
                ev["poses"] = self._part("poses")
        return ev if len(ev) > 2 else None

    def _part(self, part: str) -> Any:
        m = self.manager
        if part == "poses":
            cells = m.cells.tolist()
            return {name: self._xy(*cells[r.index]) for name, r in m.robots.items()}
        if part == "robots":
            return {
                name: {"up": r.up, "task": _task(r.busy, r.move_event)}
                for name, r in m.robots.items()
            }
        return [self._object(o) for o in m.state.objects]

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
