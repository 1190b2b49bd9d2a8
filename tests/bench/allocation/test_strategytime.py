"""The strategy mission-time bench: its scenarios, team files and verdict (no runs)."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.bench.allocation import strategytime as st
from btcap.sim.world.model import load_team


def test_the_scenarios_and_the_naive_team_files(tmp_path: Path) -> None:
    files = st._team_files(tmp_path)
    six = st.scenario("six", 3, "auction", files[("six", "naive")], hold_down_s=0.0)
    assert (len(six.robots), six.objects, six.object_workers, six.seed) == (6, 20, 4, 3)
    assert sorted(r.model for r in six.robots) == ["bebop"] * 2 + ["husky"] * 2 + ["spot"] * 2
    assert (six.allocation.strategy, six.allocation.hold_down_s) == ("auction", 0.0)
    assert all(m.bids_from_here for m in load_team(six.team_file or "").values())
    known = st.scenario("known-5", 1, "optimal", files[("known", "aware")])
    assert len(known.robots) == 5
    assert known.allocation.hold_down_s == 60.0
    assert not any(m.bids_from_here for m in load_team(known.team_file or "").values())
    with pytest.raises(ValueError, match="scenario 'seven'"):
        st.scenario("seven", 1, "optimal", files[("six", "aware")])


def test_the_default_is_judged_against_the_best_other_strategy_seed_by_seed() -> None:
    row = {"mission_s": {"optimal": {"1": 101.0, "2": 90.0}, "auction": {"1": 100.0, "2": 95.0}}}
    row["mission_s"]["sequential"] = {"1": 110.0, "2": 80.0}
    assert st._vs_best(row, "optimal") == [pytest.approx(1.01), pytest.approx(90 / 80)]
    counts = {"optimal": {"undone": 0}}
    out = {"rows": {"a": {**row, "counts": counts}}}
    assert st._met(out, "optimal") is False  # seed 2: 1.125
    row["mission_s"]["sequential"]["2"] = 100.0
    assert st._met(out, "optimal") is True
    counts["optimal"]["undone"] = 1
    assert st._met(out, "optimal") is False


def test_every_strategy_is_judged_against_the_best_of_the_others() -> None:
    # seed 1: auction is 5 % over the best (optimal), seed 2: optimal is 2 % over auction
    row = {"mission_s": {"optimal": {"1": 100.0, "2": 102.0}, "auction": {"1": 105.0, "2": 100.0}}}
    row["mission_s"]["sequential"] = {"1": 100.5, "2": 100.9}
    assert st._over(row) == {"optimal": 1, "auction": 1, "sequential": 0}


def test_the_command_line_names_what_it_expected() -> None:
    with pytest.raises(SystemExit):
        st.main(["--scenarios", "nine"])
    with pytest.raises(SystemExit):
        st.main(["--bids", "clever"])
