"""``btcap run --record`` killed outright (SIGKILL: no end of the run is written): the
recording is read up to its last whole line or chunk, and ``btcap replay`` says where it
breaks off and what it read before anything else."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from btcap.cli import main
from btcap.monitor.record import RecordError, read_recording

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"

pytestmark = pytest.mark.slow


def _readable(path: Path) -> int:
    """Events a recording being written holds so far (0 while it has none whole)."""
    try:
        return len(read_recording(path)[0])
    except (RecordError, OSError):
        return 0


@pytest.mark.parametrize("name", ["run.jsonl", "run.mcap"])
def test_a_recording_of_a_killed_run_says_what_it_read(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = tmp_path / name
    # Speed-up 10: a 262 s mission lasts some 26 s of wall time; an MCAP chunk closes
    # every 60 s of its clock (6 s), JSON Lines are written at every batch.
    argv = [sys.executable, "-m", "btcap", "run", str(SMALL), "--quiet", "--speedup", "10"]
    proc = subprocess.Popen(
        [*argv, "--out", str(tmp_path / "out"), "--record", str(record)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while _readable(record) < 10 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL  # killed, not ended
    events, cut = read_recording(record)
    assert len(events) >= 10
    assert not [e for e in events if e["k"] == "finished"]
    assert cut is not None
    assert cut.startswith(f"{record}: ")
    assert "a run that was killed?" in cut
    assert f"read {len(events)} events, up to " in cut
    assert main(["replay", str(record), "--to-mcap", str(tmp_path / "copy.mcap")]) == 0
    assert capsys.readouterr().err == f"btcap: warning: {cut}\n"
