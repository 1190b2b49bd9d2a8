"""Hand-overs that would come undone: foreseen for exchanges, held down for any move,
on explicit costs and time."""

from __future__ import annotations

import pytest

from btcap.team.core.exchange import Running, find_exchanges
from btcap.team.core.handovers import HOLD_S, Handovers, comes_back
from btcap.team.ids import ExecutionId

TH, TS = ExecutionId("base", "husky's", 1), ExecutionId("base", "spot's", 2)


def test_a_spot_does_not_hand_its_identify_to_a_husky_it_would_take_back_from() -> None:
    # issue 33: the husky (h) drives 40 to its goal, then identifies for 60 (cost 2/m);
    # the spot (s) is 30 from its Identify and next to the husky's goal. Priced now, the
    # swap pays (140 + 40 -> 30 + 105); but the spot does the husky's task in 10 and then
    # its own Identify for 40 in all: less than the husky's 105, so once free it would
    # take its Identify back, and the husky drove for nothing.
    running = [Running(TH, "h", 140.0), Running(TS, "s", 40.0)]
    cross = {("s", TH): 10.0, ("h", TS): 105.0}
    assert comes_back(received=10.0, held=40.0, taken=105.0, margin=0.2)
    assert find_exchanges(running, cross, 0.2) == []
    # crossing huskies (each next to the other's goal) still swap: neither comes back
    assert not comes_back(received=1.0, held=10.0, taken=1.0, margin=0.2)
    fair = [Running(TH, "h", 10.0), Running(TS, "s", 10.0)]
    assert len(find_exchanges(fair, {("s", TH): 1.0, ("h", TS): 1.0}, 0.2)) == 1


def test_a_task_is_not_handed_back_within_the_hold_down() -> None:
    h = Handovers()
    assert h.allows("node", "a", 0.0)
    assert not h.moved("node", "a", "b", 10.0)
    assert h.barred("node", 10.0) == {"a"}
    assert not h.allows("node", "a", 10.0 + HOLD_S - 0.5)
    assert h.allows("node", "c", 20.0)  # on to a third robot: fine
    assert h.allows("node", "a", 10.0 + HOLD_S)  # the hold-down is over
    assert h.barred("other", 10.0) == frozenset()


def test_a_hand_over_back_within_the_hold_down_is_counted_as_undone() -> None:
    h = Handovers(hold_s=0.0)  # no hold-down: a hand-over back is allowed, and counted
    h.moved("node", "a", "b", 0.0)
    assert h.allows("node", "a", 1.0)
    assert h.moved("node", "b", "a", 1.0)
    held = Handovers()
    held.moved("node", "a", "b", 0.0)
    assert held.moved("node", "b", "a", 59.0)  # back to a within 60 s: undone
    assert not held.moved("node", "a", "b", 200.0)  # long after: a move like any other


def test_a_task_is_not_handed_back_through_a_third_robot_either() -> None:
    """a -> b -> c, then back to a within the hold-down undoes the move from a as surely
    as a -> b -> a: barred (and counted, with no hold-down), as is b."""
    h = Handovers()
    h.moved("node", "a", "b", 0.0)
    assert not h.moved("node", "b", "c", 10.0)
    assert h.barred("node", 20.0) == {"a", "b"}
    assert not h.allows("node", "a", 20.0)
    assert h.allows("node", "a", HOLD_S)  # its hold-down is over; b's is not
    assert h.barred("node", HOLD_S) == {"b"}
    free = Handovers(hold_s=0.0)
    free.moved("node", "a", "b", 0.0)
    free.moved("node", "b", "c", 10.0)
    assert free.allows("node", "a", 20.0)
    assert free.moved("node", "c", "a", 20.0)  # back to a 20 s after it left: undone


def test_many_tasks_handed_over_long_ago_are_forgotten() -> None:
    h = Handovers()
    for n in range(100):
        h.moved(n, "a", "b", float(n))
    h.moved("late", "a", "b", 1000.0)
    assert len(h._left) <= 65
    with pytest.raises(ValueError, match="hold_s"):
        Handovers(hold_s=-1.0)
