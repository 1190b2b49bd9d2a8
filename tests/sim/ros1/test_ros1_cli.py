"""``btcap run --ros1`` refuses what cannot go over ROS 1 in one line, before starting
anything (no ROS needed: these run everywhere)."""

from __future__ import annotations

from pathlib import Path

import pytest

import btcap.cli
from btcap.cli import main

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() would configure structlog onto this test's captured stderr."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("btcap: error: ")
    assert err.count("\n") == 1, err
    return err


def test_ros1_is_not_for_the_fast_mode(capsys: pytest.CaptureFixture[str]) -> None:
    err = one_line(capsys, ["run", str(SMALL), "--ros1", "--fast"])
    assert "--ros1 runs the robots in this process on the wall clock: not with --fast" in err


def test_one_ros_version_at_a_time(capsys: pytest.CaptureFixture[str]) -> None:
    err = one_line(capsys, ["run", str(SMALL), "--ros1", "--ros2"])
    assert "--ros1 and --ros2: one ROS version at a time" in err


def test_a_scenario_block_asking_for_ros1_is_named(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    scenario = tmp_path / "small-ros1.yaml"
    scenario.write_text(SMALL.read_text() + "\nros:\n  backend: ros1\n")
    err = one_line(capsys, ["run", str(scenario), "--distributed"])
    assert f"{scenario}: ros: --ros1 runs the robots in this process" in err
