"""Distance fields: the vectorised wavefront must be exactly a plain BFS."""

from __future__ import annotations

import math
from collections import deque

import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from btcap.sim import DistanceCache, GridMap, as_cell, distance_field, path_length


def plain_bfs(free: NDArray[np.bool_], goal: tuple[int, int]) -> NDArray[np.int32]:
    """Textbook 4-connected BFS, one cell at a time: the oracle."""
    height, width = free.shape
    dist = np.full((height, width), -1, dtype=np.int32)
    dist[goal] = 0
    queue = deque([goal])
    while queue:
        row, col = queue.popleft()
        for d_row, d_col in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            r, c = row + d_row, col + d_col
            if 0 <= r < height and 0 <= c < width and free[r, c] and dist[r, c] < 0:
                dist[r, c] = dist[row, col] + 1
                queue.append((r, c))
    return dist


@st.composite
def maps_with_goal(draw: st.DrawFn) -> tuple[NDArray[np.bool_], tuple[int, int]]:
    shape = draw(st.tuples(st.integers(1, 14), st.integers(1, 14)))
    free = draw(hnp.arrays(np.bool_, shape))
    cells = np.argwhere(free)
    if len(cells) == 0:
        free[0, 0] = True
        cells = np.argwhere(free)
    goal = cells[draw(st.integers(0, len(cells) - 1))]
    return free, (int(goal[0]), int(goal[1]))


@settings(max_examples=50, deadline=None)
@given(maps_with_goal())
def test_wavefront_equals_plain_bfs(case: tuple[NDArray[np.bool_], tuple[int, int]]) -> None:
    free, goal = case
    field = distance_field(free, goal)
    assert field.dtype == np.int32
    assert field.shape == free.shape
    np.testing.assert_array_equal(field, plain_bfs(free, goal))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_wavefront_equals_plain_bfs_on_caves(seed: int) -> None:
    grid = GridMap.generate_cave(70, 45, seed=seed)
    rng = np.random.default_rng(seed)
    for goal in grid.random_free_cells(3, rng):
        cell = as_cell(goal)
        np.testing.assert_array_equal(distance_field(grid.free, cell), plain_bfs(grid.free, cell))


def test_walls_and_other_components_are_unreachable() -> None:
    free = np.array([[1, 1, 0, 1], [1, 0, 0, 1]], dtype=bool)
    field = distance_field(free, (0, 0))
    np.testing.assert_array_equal(field, [[0, 1, -1, -1], [1, -1, -1, -1]])


@pytest.mark.parametrize("goal", [(0, 2), (5, 0), (-1, 0), (0, 9)])
def test_goal_must_be_a_free_cell(goal: tuple[int, int]) -> None:
    free = np.array([[1, 1, 0, 1]], dtype=bool)
    with pytest.raises(ValueError, match="not a free cell"):
        distance_field(free, goal)


def test_grid_must_be_2d_bool() -> None:
    with pytest.raises(ValueError, match="2-D bool"):
        distance_field(np.ones((3, 3), dtype=np.int8), (0, 0))
    with pytest.raises(ValueError, match="2-D bool"):
        distance_field(np.ones(3, dtype=bool), (0, 0))


def test_as_cell_normalises_and_rejects() -> None:
    assert as_cell(np.array([3, 4])) == (3, 4)
    assert as_cell([1, 2]) == (1, 2)
    with pytest.raises(ValueError, match="row, col"):
        as_cell((1, 2, 3))


def test_path_length_in_metres_and_inf_when_unreachable() -> None:
    free = np.array([[1, 1, 1, 0, 1]], dtype=bool)
    field = distance_field(free, (0, 0))
    assert path_length(field, (0, 2)) == 2.0
    assert path_length(field, (0, 2), cell_size_m=0.5) == 1.0
    assert path_length(field, (0, 4)) == math.inf
    with pytest.raises(ValueError, match="outside"):
        path_length(field, (1, 0))


def test_cache_counts_hits_and_misses() -> None:
    grid = GridMap.generate_cave(40, 30, seed=3)
    cache = DistanceCache(grid.free, maxsize=4)
    first = cache.get(grid.start)
    again = cache.get(np.array(grid.start))
    assert first is again
    assert (cache.hits, cache.misses) == (1, 1)
    np.testing.assert_array_equal(first, distance_field(grid.free, grid.start))
    assert grid.start in cache
    assert len(cache) == 1


def test_cache_evicts_least_recently_used() -> None:
    free = np.ones((4, 4), dtype=bool)
    cache = DistanceCache(free, maxsize=2)
    cache.get((0, 0))
    cache.get((1, 1))
    cache.get((0, 0))  # (1, 1) is now the oldest
    cache.get((2, 2))
    assert (0, 0) in cache
    assert (1, 1) not in cache
    assert (2, 2) in cache
    assert len(cache) == 2
    cache.get((1, 1))
    assert (cache.hits, cache.misses) == (1, 4)
    cache.clear()
    assert len(cache) == 0


def test_cached_fields_are_read_only() -> None:
    cache = DistanceCache(np.ones((3, 3), dtype=bool))
    field = cache.get((1, 1))
    with pytest.raises(ValueError, match="read-only"):
        field[0, 0] = 7
    assert not cache.free.flags.writeable


def test_cache_size_must_be_positive() -> None:
    with pytest.raises(ValueError, match="maxsize"):
        DistanceCache(np.ones((2, 2), dtype=bool), maxsize=0)
