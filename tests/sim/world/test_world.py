"""The world: vectorised steps equal the per-robot loop; arrivals, radii and costs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from btcap.sim import DistanceCache, GridMap, World, distance_field

CORRIDOR = GridMap.from_array(np.ones((1, 10), dtype=bool), start=(0, 0), decon_area=(0, 9))
SPLIT = GridMap.from_array(
    np.array([[1, 1, 0, 1], [1, 1, 0, 1]], dtype=bool), start=(0, 0), decon_area=(1, 1)
)


def assert_same(a: World, b: World) -> None:
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.moving, b.moving)
    np.testing.assert_array_equal(a.active, b.active)
    np.testing.assert_array_equal(a.progress, b.progress)
    np.testing.assert_array_equal(a.travelled_m, b.travelled_m)
    np.testing.assert_array_equal(a.goals, b.goals)


def random_world(seed: int, robots: int, goals: int) -> tuple[World, NDArray[np.intp]]:
    rng = np.random.default_rng(seed)
    grid = GridMap.generate_cave(36, 24, seed=seed % 7)
    world = World(grid, cache_size=8)
    pool = grid.random_free_cells(goals, rng, replace=True)
    for cell in grid.random_free_cells(robots, rng, replace=True):
        world.add_robot(cell, speed_mps=float(rng.uniform(0.2, 4.0)))
    for i in range(robots):
        if rng.random() < 0.8:
            world.set_goal(i, pool[rng.integers(goals)])
    return world, pool


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    robots=st.integers(1, 40),
    goals=st.integers(1, 12),
    dts=st.lists(st.sampled_from([0.0, 0.1, 0.25, 0.5, 1.0, 2.5]), min_size=1, max_size=25),
)
def test_vectorised_step_equals_loop_step(
    seed: int, robots: int, goals: int, dts: list[float]
) -> None:
    world, pool = random_world(seed, robots, goals)
    loop = world.copy()
    rng = np.random.default_rng(seed + 1)
    for dt in dts:
        np.testing.assert_array_equal(world.step(dt), loop.step_loop(dt))
        assert_same(world, loop)
        # The same interventions on both: new goals, pre-emption, failure and return.
        i = int(rng.integers(robots))
        action = rng.integers(4)
        for w in (world, loop):
            if action == 0 and w.active[i]:
                w.set_goal(i, pool[(i + seed) % goals])
            elif action == 1:
                w.stop(i)
            elif action == 2:
                w.deactivate(i)
            else:
                w.activate(i)


def test_step_loop_equals_step_with_many_distinct_goals() -> None:
    grid = GridMap.generate_cave(60, 40, seed=1)
    rng = np.random.default_rng(0)
    world = World(grid, cache_size=4)
    for cell in grid.random_free_cells(200, rng):
        world.add_robot(cell, speed_mps=float(rng.uniform(0.5, 3.0)))
    goals = grid.random_free_cells(200, rng)
    for i in range(200):
        world.set_goal(i, goals[i])
    loop = world.copy()
    arrived_v: list[int] = []
    arrived_l: list[int] = []
    for _ in range(400):
        arrived_v += world.step(1.0).tolist()
        arrived_l += loop.step_loop(1.0).tolist()
    assert_same(world, loop)
    assert arrived_v == arrived_l
    assert sorted(arrived_v) == list(range(200))
    np.testing.assert_array_equal(world.positions, goals)


def test_robot_arrives_and_is_reported_once() -> None:
    world = World(CORRIDOR)
    robot = world.add_robot((0, 0), speed_mps=1.0)
    world.set_goal(robot, (0, 9))
    reports = [world.step(1.0).tolist() for _ in range(12)]
    assert reports[8] == [robot]
    assert all(r == [] for i, r in enumerate(reports) if i != 8)
    assert world.position(robot) == (0, 9)
    assert not world.moving[robot]
    assert world.travelled_m[robot] == 9.0
    assert world.progress[robot] == 0.0


def test_several_cells_per_step_and_fractional_speed() -> None:
    world = World(CORRIDOR)
    fast = world.add_robot((0, 0), speed_mps=4.0)
    slow = world.add_robot((0, 0), speed_mps=0.5)
    world.set_goal(fast, (0, 9))
    world.set_goal(slow, (0, 9))
    world.step(1.0)
    assert world.position(fast) == (0, 4)
    assert world.position(slow) == (0, 0)
    assert world.progress[slow] == 0.5
    world.step(1.0)
    assert world.position(slow) == (0, 1)
    assert world.step(1.0).tolist() == [fast]  # 12 cells of budget, 9 needed
    assert world.position(fast) == (0, 9)
    assert world.travelled_m[fast] == 9.0


def test_speed_and_distance_are_metric() -> None:
    grid = GridMap.from_array(np.ones((1, 10), dtype=bool), cell_size_m=2.0)
    world = World(grid)
    robot = world.add_robot((0, 0), speed_mps=2.0)
    assert world.speed_cells_per_s[robot] == 1.0
    world.set_goal(robot, (0, 3))
    world.step(2.0)
    assert world.position(robot) == (0, 2)
    assert world.travelled_m[robot] == 4.0


def test_goal_at_own_cell_arrives_on_next_step() -> None:
    world = World(CORRIDOR)
    robot = world.add_robot((0, 4))
    world.set_goal(robot, (0, 4))
    assert world.moving[robot]
    assert world.step(0.0).tolist() == [robot]
    assert world.travelled_m[robot] == 0.0


def test_robots_follow_shortest_paths() -> None:
    grid = GridMap.generate_cave(50, 35, seed=8)
    rng = np.random.default_rng(3)
    world = World(grid)
    starts = grid.random_free_cells(30, rng)
    goal = grid.decon_area
    for cell in starts:
        world.set_goal(world.add_robot(cell, speed_mps=1.5), goal)
    while world.moving.any():
        world.step(1.0)
    field = distance_field(grid.free, goal)
    np.testing.assert_array_equal(world.travelled_m, field[starts[:, 0], starts[:, 1]])


def test_stop_deactivate_and_activate() -> None:
    world = World(CORRIDOR)
    robot = world.add_robot((0, 0), speed_mps=1.5)
    world.set_goal(robot, (0, 9))
    world.step(1.0)
    world.stop(robot)
    assert not world.moving[robot]
    assert world.progress[robot] == 0.0
    world.step(1.0)
    assert world.position(robot) == (0, 1)
    world.set_goal(robot, (0, 9))
    world.deactivate(robot)
    assert not world.active[robot]
    assert world.step(5.0).tolist() == []
    assert world.position(robot) == (0, 1)
    with pytest.raises(ValueError, match="inactive"):
        world.set_goal(robot, (0, 5))
    world.activate(robot)
    world.set_goal(robot, (0, 5))
    assert world.step(10.0).tolist() == [robot]


def test_set_goal_rejects_walls_unreachable_goals_and_bad_indices() -> None:
    world = World(SPLIT)
    robot = world.add_robot((0, 0))
    with pytest.raises(ValueError, match="not a free cell"):
        world.set_goal(robot, (0, 2))
    with pytest.raises(ValueError, match="not reachable"):
        world.set_goal(robot, (1, 3))
    assert not world.moving[robot]
    with pytest.raises(IndexError):
        world.set_goal(5, (0, 1))
    world.set_goal(robot, (1, 1))
    world.step(10.0)
    assert world.position(robot) == (1, 1)


@pytest.mark.parametrize(
    ("cell", "kwargs", "message"),
    [
        ((0, 2), {}, "not a free cell"),
        ((0, 0), {"speed_mps": 0.0}, "speed"),
        ((0, 0), {"speed_mps": math.inf}, "speed"),
        ((0, 0), {"cost_factor": -1.0}, "cost factor"),
    ],
)
def test_add_robot_validates(cell: tuple[int, int], kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        World(SPLIT).add_robot(cell, **kwargs)


def test_step_rejects_bad_dt() -> None:
    world = World(CORRIDOR)
    for dt in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="dt"):
            world.step(dt)
        with pytest.raises(ValueError, match="dt"):
            world.step_loop(dt)


def test_world_grows_beyond_initial_capacity() -> None:
    world = World(CORRIDOR)
    assert world.step(1.0).tolist() == []
    assert world.positions.shape == (0, 2)
    for i in range(100):
        assert world.add_robot((0, i % 10)) == i
    assert len(world) == 100
    np.testing.assert_array_equal(world.positions[:, 1], np.arange(100) % 10)
    np.testing.assert_array_equal(world.goals, -np.ones((100, 2)))


def test_copy_is_independent() -> None:
    world = World(CORRIDOR)
    robot = world.add_robot((0, 0))
    world.set_goal(robot, (0, 9))
    twin = world.copy()
    twin.step(3.0)
    assert world.position(robot) == (0, 0)
    assert twin.position(robot) == (0, 3)
    assert twin.cache is world.cache


def test_cache_must_match_map() -> None:
    with pytest.raises(ValueError, match="different map"):
        World(CORRIDOR, cache=DistanceCache(np.ones((2, 2), dtype=bool)))


def test_state_views_are_read_only() -> None:
    world = World(CORRIDOR)
    world.add_robot((0, 0))
    with pytest.raises(ValueError, match="read-only"):
        world.active[0] = False


@settings(max_examples=50, deadline=None)
@given(
    cell_size=st.sampled_from([0.25, 0.5, 1.0, 2.0]),
    radius=st.floats(0.0, 40.0),
    seed=st.integers(0, 1000),
)
def test_within_radius_equals_brute_force(cell_size: float, radius: float, seed: int) -> None:
    grid = GridMap.from_array(np.ones((30, 40), dtype=bool), cell_size_m=cell_size)
    rng = np.random.default_rng(seed)
    world = World(grid)
    robot = world.add_robot(grid.random_free_cells(1, rng)[0])
    points = rng.integers(0, (30, 40), size=(60, 2))
    mask = world.within_radius(robot, radius, points)
    x0, y0 = grid.to_metres(world.position(robot))
    expected = [math.hypot(x - x0, y - y0) <= radius for x, y in grid.to_metres(points).tolist()]
    assert mask.tolist() == expected


def test_travel_cost_is_path_length_times_cost_factor() -> None:
    grid = GridMap.generate_cave(40, 30, seed=6, cell_size_m=0.5)
    rng = np.random.default_rng(2)
    world = World(grid)
    for cell, factor in zip(grid.random_free_cells(3, rng), (2.0, 1.25, 1.0), strict=True):
        world.add_robot(cell, cost_factor=factor)
    target = grid.decon_area
    field = distance_field(grid.free, target)
    costs = world.travel_costs(target)
    for i, factor in enumerate((2.0, 1.25, 1.0)):
        expected = float(field[world.position(i)]) * 0.5 * factor
        assert world.travel_cost(i, target) == pytest.approx(expected)
        assert costs[i] == pytest.approx(expected)
    assert world.cache.misses == 1
    assert world.cache.hits >= 3


def test_travel_cost_is_inf_without_a_path() -> None:
    world = World(SPLIT)
    robot = world.add_robot((0, 0), cost_factor=2.0)
    assert world.travel_cost(robot, (0, 3)) == math.inf
    assert world.travel_costs((0, 3)).tolist() == [math.inf]
    assert world.travel_cost(robot, (1, 1)) == 4.0
    with pytest.raises(ValueError, match="not a free cell"):
        world.travel_cost(robot, (0, 2))
