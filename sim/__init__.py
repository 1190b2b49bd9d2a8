"""Simulation: a vectorised numpy grid world (cave maps, distance fields, moving robots)."""

from sim.distance import (
    UNREACHABLE,
    Cell,
    CellLike,
    DistanceCache,
    as_cell,
    distance_field,
    path_length,
)
from sim.grid import GridMap, MapError
from sim.world import World

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
