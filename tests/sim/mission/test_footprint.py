"""A map's memory is estimated from its size alone, and one too big is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from btcap.sim import GridMap
from btcap.sim.mission.footprint import (
    MAP_BYTES_PER_CELL,
    MAX_CELLS,
    map_bytes,
    map_too_big,
    memory_limit,
)
from btcap.sim.world.distance import distance_field

GIB = 1 << 30


def test_the_estimate_covers_the_map_and_every_cached_distance_field() -> None:
    one = map_bytes(1, robots=1)
    assert one >= MAP_BYTES_PER_CELL + 4 * (256 + 64)
    assert map_bytes(1000, robots=1) == 1000 * one
    assert map_bytes(1, robots=4) - map_bytes(1, robots=3) >= 4 * 64  # a robot's cache


def test_the_estimate_is_above_what_generating_a_cave_and_a_field_takes() -> None:
    import tracemalloc

    tracemalloc.start()
    try:
        grid = GridMap.generate_cave(300, 200, seed=1)
        distance_field(grid.free, grid.start)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < map_bytes(300 * 200, robots=0)
    assert peak / (300 * 200) < MAP_BYTES_PER_CELL + 4 + 25  # the map, a field and its BFS


def test_a_map_that_fits_passes() -> None:
    assert map_too_big(80, 120, robots=3, memory=GIB) is None


def test_a_map_larger_than_memory_is_refused_with_the_estimate() -> None:
    why = map_too_big(4000, 5000, robots=3, memory=16 * GIB)
    assert why is not None
    assert why.startswith("a 5000x4000 map needs up to 35.8 GiB")
    assert "3 robot(s), more than the 16.0 GiB of memory here" in why


def test_more_cells_than_32_bit_distances_count_is_refused_whatever_the_memory() -> None:
    why = map_too_big(100_000, 100_000, robots=1, memory=1 << 60)
    assert why == f"100000x100000 = 10000000000 cells; at most {MAX_CELLS} (distances are 32-bit)"
    assert np.iinfo(np.int32).max == MAX_CELLS


def test_this_machines_memory_is_known() -> None:
    memory = memory_limit()
    if memory is None:
        pytest.skip("this system does not say how much memory it has")
    assert 64 * (1 << 20) < memory < 1 << 50
