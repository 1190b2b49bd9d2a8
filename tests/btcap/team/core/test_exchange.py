"""Exchanges of running work between busy robots: the choice and the two-phase hand-over."""

from __future__ import annotations

import pytest

from btcap.team.core.body import Body
from btcap.team.core.exchange import Ledger, Running, find_exchanges
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


# -- the ledger: which exchanges are worth an auction -----------------------------------

RA, RB, RC = Running(TA, "a", 10.0), Running(TB, "b", 10.0), Running(TC, "c", 10.0)


def test_a_cycle_nobody_bid_for_is_worth_a_try_once() -> None:
    ledger = Ledger()
    assert ledger.may_pay([RA, RB], 0.2)  # unknown legs priced 0
    ledger.leg(TB, TA, 17.0)  # b would take ta for 17: more than the pair may cost
    assert not ledger.may_pay([RA, RB], 0.2)
    assert not ledger.may_pay([RB, RA], 0.2)  # the same cycle, started at the other leg
    ledger.leg(TC, TB, None)  # c declined tb
    assert not ledger.may_pay([RB, RC], 0.0)


def test_a_cycle_is_asked_again_once_the_robots_progress_could_make_it_pay() -> None:
    ledger = Ledger()
    ledger.holder(TA, 10.0)
    ledger.holder(TB, 10.0)
    ledger.leg(TB, TA, 9.0)  # b for ta; b had 10 left then
    ledger.leg(TA, TB, 9.0)  # 18 against 20: within the margin
    assert not ledger.may_pay([RA, RB], 0.2)
    # Both drove 4 on: each leg may have fallen by as much; a gain of 2 is still too little
    ledger.holder(TA, 6.0)
    ledger.holder(TB, 6.0)
    assert ledger.leg_cost(TB, TA) == 5.0
    assert not ledger.may_pay([RA, RB], 0.2)  # 10 against 12
    ledger.holder(TA, 4.0)  # 6 on: 6 against 8 may pay
    ledger.holder(TB, 4.0)
    assert ledger.may_pay([RA, RB], 0.2)
    ledger.holder(TB, 20.0)  # a rise is no progress: the legs stay as bid
    assert ledger.leg_cost(TB, TA) == 9.0


def test_cycles_come_pairs_first_then_both_chains_and_start_at_an_unknown_leg() -> None:
    ledger = Ledger()
    ledger.leg(TB, TA, 1.0)  # a -> b known (cheap)
    cycles = list(ledger.cycles([RA, RB, RC], 0.2))
    heads = [tuple(t.execution for t in c) for c in cycles]
    assert heads == [
        (TB, TA),  # the pair a, b starts at the leg b -> a, nobody bid for it yet
        (TA, TC),
        (TB, TC),
        (TB, TC, TA),  # a -> b -> c -> a: a -> b is known, start at b -> c
        (TA, TC, TB),
    ]
    assert [len(c) for c in ledger.cycles([RA, RB, RC], 0.2, chain=2)] == [2, 2, 2]
    ledger.keep({TA, TB})  # tc ended: what was said about it is forgotten
    assert ledger.leg_cost(TB, TA) == 1.0
    ledger.keep({TA})
    assert ledger.leg_cost(TB, TA) is None


def test_chains_are_looked_for_among_the_first_tasks_only() -> None:
    ta, tb, tc, td = (Running(ExecutionId("base", f"u{n}", n), f"r{n}", 10.0) for n in range(4))
    assert sum(len(c) == 3 for c in Ledger().cycles([ta, tb, tc, td], 0.2)) == 8
    assert sum(len(c) == 3 for c in Ledger().cycles([ta, tb, tc, td], 0.2, chain_of=3)) == 2
