"""The simulator of the paper's mission, and the fault simulation of whole teams.

Start with :mod:`btcap.sim.cli` (``btcap run``), then by role, each importing only those
above it in this list: :mod:`~btcap.sim.world` (the grid world and its robots),
:mod:`~btcap.sim.mission` (the mission, its capabilities and scenarios),
:mod:`~btcap.sim.running` (running and recording a scenario, in this process or one
process a robot), :mod:`~btcap.sim.ros1` and :mod:`~btcap.sim.ros2` (the same behind ROS,
sharing :mod:`~btcap.sim.rosbase`), and :mod:`~btcap.sim.faults` (``btcap sim-test``)."""

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from btcap.sim.world.distance import (
        UNREACHABLE,
        Cell,
        CellLike,
        DistanceCache,
        as_cell,
        distance_field,
        path_length,
    )
    from btcap.sim.world.grid import GridMap, MapError
    from btcap.sim.world.motion import World

#: Imported on first use (see btcap._lazy): ``btcap --help`` lists ``btcap run`` without
#: loading numpy.
_EXPORTS = {
    "btcap.sim.world.distance": (
        "UNREACHABLE",
        "Cell",
        "CellLike",
        "DistanceCache",
        "as_cell",
        "distance_field",
        "path_length",
    ),
    "btcap.sim.world.grid": ("GridMap", "MapError"),
    "btcap.sim.world.motion": ("World",),
}

if not TYPE_CHECKING:
    from btcap._lazy import lazy_exports

    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

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
