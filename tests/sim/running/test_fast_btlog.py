"""``btcap run --btlog``: the mission tree's run as a ``.btlog`` for Groot2, the same for
the same scenario and seed (times are the virtual clock's), ending as the mission did."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import btcap.cli
from btcap.bt.files.btcpp_status import IDLE, SUCCESS
from btcap.bt.files.btlog import read_btlog
from btcap.cli import main

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() configures structlog globally, onto this test's captured stderr."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def test_two_fast_runs_log_the_same_mission_tree_run(tmp_path: Path) -> None:
    logs = []
    for name in ("one", "two"):
        out, log = tmp_path / name, tmp_path / f"{name}.btlog"
        assert (
            main(["run", str(SMALL), "--fast", "--quiet", "--out", str(out), "--btlog", str(log)])
            == 0
        )
        logs.append(read_btlog(log))
    first, second = logs
    assert first.xml == second.xml
    assert first.transitions == second.transitions  # times too: the virtual clock's
    assert '<Parallel name="mission" _uid="1" failure_count="-1"' in first.xml
    assert len(first.transitions) > 50
    # the mission succeeded: the root's result, then the tree resets it, at mission time
    assert [(u, s) for _, u, s in first.transitions[-2:]] == [(1, SUCCESS), (1, IDLE)]
    mission_s = json.loads((tmp_path / "one" / "result.json").read_text())["mission_time_s"]
    assert abs(first.transitions[-1][0] / 1e6 - mission_s) <= 1.0


def test_a_log_not_named_btlog_is_refused_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["run", str(SMALL), "--fast", "--quiet", "--out", str(tmp_path / "out")]
    assert main([*args, "--btlog", str(tmp_path / "mission.log")]) == 2
    assert "--btlog" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
