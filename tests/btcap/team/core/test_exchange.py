"""Exchanges of running work between busy robots: the choice and the two-phase hand-over."""

from __future__ import annotations

import pytest

from btcap.team.core.body import Body
from btcap.team.core.exchange import Running, find_exchanges
from btcap.team.ids import ExecutionId

TA, TB, TC = (ExecutionId("base", f"t{n}", n) for n in (1, 2, 3))


def test_two_robots_driving_to_each_others_goals_swap() -> None:
    # a runs ta (10 left), b runs tb (10 left); each is 1 from the other's goal
    running = [Running(TA, "a", 10.0), Running(TB, "b", 10.0)]
    cross = {("b", TA): 1.0, ("a", TB): 1.0}
    (ex,) = find_exchanges(running, cross, 0.2)
    assert {(leg.execution, leg.frm, leg.to) for leg in ex.legs} == {(TA, "a", "b"), (TB, "b", "a")}
    assert (ex.before, ex.after, ex.gain) == (20.0, 2.0, 18.0)


def test_a_gain_within_the_margin_exchanges_nothing() -> None:
    running = [Running(TA, "a", 10.0), Running(TB, "b", 10.0)]
    assert find_exchanges(running, {("b", TA): 8.5, ("a", TB): 8.5}, 0.2) == []  # 17 > 16
    assert len(find_exchanges(running, {("b", TA): 7.9, ("a", TB): 8.0}, 0.2)) == 1


def test_a_robot_that_cannot_take_the_other_task_blocks_the_swap() -> None:
    running = [Running(TA, "a", 10.0), Running(TB, "b", 10.0)]
    assert find_exchanges(running, {("b", TA): 1.0}, 0.0) == []
    assert find_exchanges(running, {("b", TA): 1.0, ("a", TB): float("inf")}, 0.0) == []


def test_a_chain_of_three_where_no_swap_pays() -> None:
    # each robot is next to the following task's goal: only the rotation helps
    running = [Running(TA, "a", 10.0), Running(TB, "b", 10.0), Running(TC, "c", 10.0)]
    cross = {("b", TA): 1.0, ("c", TB): 1.0, ("a", TC): 1.0}
    cross |= {("a", TB): 30.0, ("b", TC): 30.0, ("c", TA): 30.0}
    assert find_exchanges(running, cross, 0.2, chain=2) == []
    (ex,) = find_exchanges(running, cross, 0.2)
    assert {(leg.execution, leg.to) for leg in ex.legs} == {(TA, "b"), (TB, "c"), (TC, "a")}
    assert ex.after == 3.0


def test_exchanges_are_disjoint_and_the_largest_gain_goes_first() -> None:
    running = [Running(TA, "a", 10.0), Running(TB, "b", 10.0), Running(TC, "c", 10.0)]
    cross = {("b", TA): 1.0, ("a", TB): 1.0, ("c", TA): 4.0, ("a", TC): 4.0}
    (ex,) = find_exchanges(running, cross, 0.0, chain=2)  # a-b (gain 18) beats a-c (12)
    assert {leg.to for leg in ex.legs} == {"a", "b"}


def test_a_robot_with_two_running_tasks_is_not_a_candidate() -> None:
    running = [Running(TA, "a", 10.0), Running(TC, "a", 5.0), Running(TB, "b", 10.0)]
    assert find_exchanges(running, {("b", TA): 1.0, ("a", TB): 1.0}, 0.0) == []


@pytest.mark.parametrize(("margin", "chain"), [(-0.1, 3), (0.2, 4)])
def test_bad_settings_are_refused(margin: float, chain: int) -> None:
    with pytest.raises(ValueError, match="exchange"):
        find_exchanges([], {}, margin, chain=chain)


def test_the_body_holds_an_exchanged_task_beside_the_one_it_hands_over() -> None:
    body = Body()
    assert body.take(TB, 10.0)
    assert body.reserve_exchange(TA, 1.0, handing=TC) is not None  # not what it runs
    assert body.reserve_exchange(TA, 1.0, handing=TB) is None
    assert body.wait_cost() is None  # takes nothing else meanwhile
    assert body.reserve_exchange(TC, 1.0, handing=TB) is not None  # one at a time
    assert body.release(TB) == TA  # commit: the old run goes, the new one has the body
    assert body.running == TA
    assert body.queued is None


def test_an_aborted_exchange_leaves_the_body_as_it_was() -> None:
    body = Body()
    body.take(TB, 10.0)
    body.reserve_exchange(TA, 1.0, handing=TB)
    assert body.release(TA) is None
    assert body.running == TB
    assert body.queued is None
    assert body.wait_cost() is None
