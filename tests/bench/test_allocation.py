"""The allocation benchmark's dynamic events, on hand-made instances with known answers."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from btcap.bench.allocation import Costs, Events, allocate, ratios

# Two tasks; r00 and r01 are there from the start, r02 joins (or stands by) and is far
# cheaper for task 0.
COST = np.array([[10.0, 50.0], [50.0, 10.0], [2.0, 60.0]])


def run(
    cost: Costs, strategy: str, events: Events, period: float | None
) -> tuple[list[int], set[int]]:
    """The team's final allocation, within a bound of wall time."""
    return asyncio.run(asyncio.wait_for(allocate(cost, strategy, events, period, seed=0), 30))


@pytest.mark.parametrize(("period", "first"), [(30.0, 2), (None, 0)])
def test_running_work_moves_to_a_robot_that_joins_only_with_re_evaluation(
    period: float | None, first: int
) -> None:
    events = Events((0.0, 0.0), join_at=(5.0,))
    final, failed = run(COST, "auction", events, period)
    assert final == [first, 1]
    assert failed == set()
    ratio, _span = ratios(COST, final, [0, 1, 2])
    assert ratio == (pytest.approx(1.0) if first == 2 else pytest.approx(20 / 12))


def test_a_failed_holder_s_task_goes_to_the_spare_and_the_reference_leaves_it_out() -> None:
    cost = np.array([[10.0], [20.0]])  # one task: r00 takes it, then fails
    final, failed = run(cost, "sequential", Events((0.0,), fail_at=(5.0,)), None)
    assert (final, failed) == ([1], {0})
    assert ratios(cost, final, [1]) == (1.0, 1.0)  # the hindsight optimum knows r00 fails


def test_tasks_that_arrive_later_take_who_is_free_then() -> None:
    cost = np.array([[1.0, 2.0], [5.0, 50.0]])  # task 1 arrives after r00 took task 0
    final, _ = run(cost, "auction", Events((0.0, 10.0)), None)
    assert final == [0, 1]
    ratio, span = ratios(cost, final, [0, 1])
    assert ratio == pytest.approx(51 / 7)  # hindsight: r01 on task 0 (5), r00 on task 1 (2)
    assert span == pytest.approx(50 / 5)
