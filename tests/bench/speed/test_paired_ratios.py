"""The recording bench's verdict: per-pair ratios, their median and its bootstrap interval."""

from __future__ import annotations

import math
import shutil

import pytest

from btcap.bench.speed.paired import instructions, median_ci, pair_ratios


def test_each_run_is_divided_by_the_base_run_of_its_own_turn() -> None:
    # load doubled the second turn: both runs of it, so its pair says what the others say
    assert pair_ratios([1.05, 2.1, 1.05], [1.0, 2.0, 1.0]) == pytest.approx([1.05] * 3)
    with pytest.raises(ValueError, match="expected pairs"):
        pair_ratios([1.0, 2.0], [1.0])


def test_the_interval_holds_the_median_and_is_the_same_for_the_same_runs() -> None:
    ratios = [1.02, 1.05, 0.99, 1.03, 1.01, 1.04, 1.00, 1.30]  # one turn hit by load
    med, low, high = median_ci(ratios)
    assert med == pytest.approx(1.025)
    assert low <= med <= high
    assert high < 1.30  # the outlier moves a median's interval little
    assert median_ci(ratios) == (med, low, high)  # seeded


def test_too_few_runs_give_no_interval() -> None:
    med, low, high = median_ci([1.0, 1.1])
    assert med == pytest.approx(1.05)
    assert math.isnan(low)
    assert math.isnan(high)


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_valgrind_counts_more_instructions_for_more_work() -> None:
    little = instructions(["sh", "-c", "true"])
    more = instructions(["sh", "-c", "i=0; while [ $i -lt 20000 ]; do i=$((i+1)); done"])
    assert little is not None
    assert more is not None
    assert more > little + 1_000_000
