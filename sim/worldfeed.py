"""The simulated world as monitor events: the map once, then what changed.

A monitor samples :meth:`WorldFeed.sample` at every batch (every simulation step on a
virtual clock), so a recording holds where every robot was, what it was doing and what
became of every object, step by step, and the same bytes in every ``--fast`` run of a
seed. Each part (poses, robots' state and task, objects) is sent whole when it changed and
not at all otherwise: robots that stand still cost nothing. The events' shapes and how
Foxglove draws them are in :mod:`btcap.monitor.scene`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from btcap.monitor.view import Event
from btcap.sim.manager import SimulationManager
from btcap.sim.store import SimObject

__all__ = ["WorldFeed"]


class WorldFeed:
    """Reads the simulation's ground truth (a :class:`SimulationManager`'s) for a monitor."""

    def __init__(self, manager: SimulationManager) -> None:
        self.manager = manager
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
        """The parts of the world that changed since the last sample (``world``), or None.
        Each part is compared by a cheap key first (the step's cells as bytes, the robots'
        operations, the objects' fields) and only built when that changed."""
        m = self.manager
        robots = m.robots.values()
        cells = m.cells
        keys = {
            "poses": cells.tobytes(),
            "robots": tuple(
                (r.up, id(r.busy[-1].event) if r.busy else id(r.move_event)) for r in robots
            ),
            "objects": tuple(
                (o.found, o.identified, o.decontaminated, o.carried_by, o.cell)
                for o in m.state.objects
            ),
        }
        ev: Event = {"t": m.now(), "k": "world"}
        for part, key in keys.items():
            if self._keys.get(part) != key:
                self._keys[part] = key
                ev[part] = self._part(part, cells)
        return ev if len(ev) > 2 else None

    def _part(self, part: str, cells: NDArray[np.intp]) -> Any:
        m = self.manager
        if part == "poses":
            return {name: self._xy(*cells[r.index].tolist()) for name, r in m.robots.items()}
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
