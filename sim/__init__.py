"""Simulation: a vectorised numpy grid world (cave maps, distance fields, moving robots)."""

from btcap.sim.distance import (
    UNREACHABLE,
    Cell,
    CellLike,
    DistanceCache,
    as_cell,
    distance_field,
    path_length,
)
from btcap.sim.grid import GridMap, MapError
from btcap.sim.world import World

__all__ = [
    "UNREACHABLE",
    "Cell",
    "CellLike",
    "DistanceCache",
    "GridMap",
    "MapError",
    "World",
    "as_cell",
    "distance_field",
    "path_length",
]
