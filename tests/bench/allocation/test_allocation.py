"""The allocation benchmark's dynamic events, on hand-made instances with known answers."""

from __future__ import annotations

import argparse
import asyncio

import numpy as np
import pytest

from btcap.bench.allocation.args import load_map, seed_list
from btcap.bench.allocation.optimum import (
    Allocation,
    Costs,
    Events,
    allocate,
    main,
    ratios,
)

# Two tasks; r00 and r01 are there from the start, r02 joins (or stands by) and is far
# cheaper for task 0.
COST = np.array([[10.0, 50.0], [50.0, 10.0], [2.0, 60.0]])


def run_full(cost: Costs, strategy: str, events: Events, period: float | None) -> Allocation:
    """What the team did, within a bound of wall time."""
    return asyncio.run(asyncio.wait_for(allocate(cost, strategy, events, period, seed=0), 30))


def run(
    cost: Costs, strategy: str, events: Events, period: float | None
) -> tuple[list[int], set[int]]:
    """The team's final allocation and the robots failed on purpose."""
    got = run_full(cost, strategy, events, period)
    return got.final, got.failed


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


@pytest.mark.parametrize(("strategy", "wave"), [("optimal", [0, 1, -1]), ("auction", [1, -1, 0])])
def test_with_more_tasks_than_robots_the_first_wave_is_priced(
    strategy: str, wave: list[int]
) -> None:
    # Two robots, three tasks: the optimum starts t0 on r00 and t1 on r01 (4); the
    # regret auction gives r00 task 2 first (it loses most by waiting), then r01 t0: 52.
    cost = np.array([[1.0, 5.0, 50.0], [2.0, 3.0, 60.0]])
    got = run_full(cost, strategy, Events((0.0, 0.0, 0.0)), None)
    assert got.final == wave
    assert ratios(cost, got.final, [0, 1])[0] == pytest.approx(1.0 if wave[2] < 0 else 13.0)
    assert got.messages >= 9  # three calls for bids to two robots and their answers
    assert got.cpu_s > 0.0


def test_seeds_and_maps_are_read_from_the_command_line() -> None:
    assert seed_list("1000-1002,7") == [1000, 1001, 1002, 7]
    with pytest.raises(argparse.ArgumentTypeError, match="expected seeds like 0-19"):
        seed_list("x-3")
    with pytest.raises(argparse.ArgumentTypeError, match="'1,5-3'"):
        seed_list("1,5-3")  # backwards: nothing to run, not an empty run
    assert load_map("cave:7").source == "<cave 80x60 seed=7>"
    with pytest.raises(argparse.ArgumentTypeError, match="cave:SEED"):
        load_map("cave:seven")


def test_the_bench_runs_every_strategy_on_chosen_instances(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("btcap.bench.allocation.optimum.write_result", lambda name, data: None)
    out = main(["--seeds", "5", "--map", "cave:7", "--sizes", "3x4", "--static"])
    assert out["seeds"] == [5, 5]
    assert out["map"] == "<cave 80x60 seed=7>"
    assert set(out["cost_ratio"]["3x4"]) >= {"auction", "optimal", "sequential", "consensus"}
    assert out["cost_ratio"]["3x4"]["optimal"]["mean"] == pytest.approx(1.0)
    assert "3x4" in capsys.readouterr().out
