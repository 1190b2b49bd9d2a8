"""When a running task's own estimate is news: rises beyond the margin, once each."""

from __future__ import annotations

import pytest

from btcap.team.core.costwatch import CostWatch
from btcap.team.ids import ExecutionId

E1 = ExecutionId("a", "root/x", 1)
E2 = ExecutionId("a", "root/y", 2)


def test_progress_is_no_news_and_a_rise_beyond_the_margin_is_news_once() -> None:
    w = CostWatch(0.2)
    assert [w.see(E1, c) for c in (100.0, 80.0, 60.0, 70.0, 71.9)] == [False] * 5
    assert w.see(E1, 72.1)  # 20 % above the lowest estimate seen (60)
    assert not w.see(E1, 80.0)  # the rise became the baseline
    assert w.see(E1, 87.0)


def test_zero_costs_and_a_zero_margin() -> None:
    w = CostWatch(0.0)
    assert not w.see(E1, 0.0)
    assert not w.see(E1, 0.0)
    assert w.see(E1, 0.5)
    with pytest.raises(ValueError, match="margin"):
        CostWatch(-0.1)


def test_ended_runs_are_forgotten_and_the_table_is_bounded() -> None:
    w = CostWatch(0.2, limit=3)
    w.see(E1, 1.0)
    w.see(E2, 1.0)
    w.keep_only([E2])
    assert not w.see(E1, 5.0)  # a new baseline, not a rise
    for n in range(10):
        w.see(ExecutionId("a", "n", 10 + n), 1.0)
    assert len(w) == 3


def test_an_estimate_that_is_not_a_number_is_no_news_and_leaves_the_baseline() -> None:
    """A NaN from an estimate (0/0 on a blocked path) must not become the baseline: every
    comparison with NaN is false, so no later rise would ever be news again."""
    w = CostWatch(0.2)
    assert not w.see(E1, float("nan"))
    assert w.see(E1, 10.0) is False  # the first real estimate is the baseline
    assert not w.see(E1, float("nan"))
    assert w.see(E1, 20.0)
    assert w.see(E1, float("inf"))  # unreachable now: the biggest rise there is
