"""How much memory a mission's map needs, known from its size alone, so that a map this
machine cannot hold is refused before anything is allocated (not with numpy's
out-of-memory traceback minutes into a run).

The estimate is the worst case of a long run: the map while it is generated and checked,
and every distance field the simulation and the robots keep once their caches are full
(4 bytes a cell each), plus the world's per-goal planes.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from btcap.sim.mission.capabilities import ROBOT_CACHE_SIZE
from btcap.sim.world.motion import CACHE_SIZE

__all__ = ["MAP_BYTES_PER_CELL", "MAX_CELLS", "map_bytes", "map_too_big", "memory_limit"]

#: The map while it is generated and checked (float64 noise, int32 labels, masks, the
#: reachable cells; measured peak 54 B), and the mission's coverage masks.
MAP_BYTES_PER_CELL = 64
#: Distances and component labels are int32.
MAX_CELLS = int(np.iinfo(np.int32).max)
_FIELD_BYTES = 4  # an int32 distance field, per cell
_PLANE_BYTES = 8  # one goal plane of the world (int32 distance + next hop), per cell


def map_bytes(cells: int, robots: int) -> int:
    """Bytes a mission on a map of ``cells`` with ``robots`` robots may need at most."""
    fields = CACHE_SIZE + ROBOT_CACHE_SIZE * robots
    planes = 2 * (robots + 1)  # a goal in use per robot, and the slab doubles as it grows
    return cells * (MAP_BYTES_PER_CELL + _FIELD_BYTES * fields + _PLANE_BYTES * planes)


def memory_limit() -> int | None:
    """This machine's memory in bytes (or its container's limit, if lower); None if the
    system does not say."""
    try:
        total: int | None = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = None
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
    except OSError:
        limit = "max"
    if limit.isdigit():
        total = min(int(limit), total) if total else int(limit)
    return total if total and total > 0 else None


def map_too_big(height: int, width: int, robots: int, *, memory: int | None = None) -> str | None:
    """Why a ``height`` x ``width`` map cannot be simulated here, or None if it can.

    ``memory`` defaults to :func:`memory_limit`."""
    cells = height * width
    if cells > MAX_CELLS:
        return f"{width}x{height} = {cells} cells; at most {MAX_CELLS} (distances are 32-bit)"
    need = map_bytes(cells, robots)
    have = memory if memory is not None else memory_limit()
    if have is not None and need > have:
        return (
            f"a {width}x{height} map needs up to {_size(need)} for its grid and the distance "
            f"fields of {robots} robot(s), more than the {_size(have)} of memory here"
        )
    return None


def _size(n: int) -> str:
    value = float(n)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if value < 1024:
            return f"{value:.1f} {unit}"
        value /= 1024
    return f"{value:.1f} TiB"
