"""A recording that cannot be written to its end (a full disk) is not announced as
recorded: ``btcap run`` says it stopped, why, and what the file holds."""

from __future__ import annotations

from pathlib import Path

import pytest

import btcap.cli
from btcap.cli import main

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
FULL = Path("/dev/full")  # every write fails with ENOSPC


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() configures structlog globally, onto this test's captured stderr."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


@pytest.mark.slow
@pytest.mark.skipif(not FULL.exists(), reason="needs /dev/full")
def test_a_recording_that_fills_the_disk_mid_run_is_said_to_have_stopped(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = tmp_path / "run.jsonl"  # (its header is buffered: the first batch fails)
    record.symlink_to(FULL)
    args = ["run", str(SMALL), "--fast", "--quiet", "--out", str(tmp_path / "out")]
    assert main([*args, "--record", str(record)]) == 0  # the run itself goes on
    said = capsys.readouterr().out
    assert f"recorded {record}" not in said
    line = next(x for x in said.splitlines() if x.startswith("recording "))
    assert f"recording {record} stopped before the end: No space left on device" in line


@pytest.mark.slow
@pytest.mark.skipif(not FULL.exists(), reason="needs /dev/full")
def test_a_recording_that_cannot_start_names_its_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = tmp_path / "run.mcap"  # (MCAP writes its header at once)
    record.symlink_to(FULL)
    args = ["run", str(SMALL), "--fast", "--quiet", "--out", str(tmp_path / "out")]
    assert main([*args, "--record", str(record)]) != 0
    said = capsys.readouterr().err
    assert f"cannot write the recording {record}: No space left on device" in said
