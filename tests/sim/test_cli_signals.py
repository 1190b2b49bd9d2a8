"""``btcap run`` stopped by SIGTERM or SIGINT ends the mission early and still writes its
result, marked interrupted (its recording too), and exits with 128 + the signal's number."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

from btcap.monitor import read_record
from btcap.sim.metrics import MissionResult

SMALL = Path(__file__).parent / "data" / "small.yaml"

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(
    ("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)], ids=["term", "int"]
)
def test_a_signal_stops_the_run_and_the_result_says_interrupted(
    tmp_path: Path, sig: signal.Signals, code: int
) -> None:
    out = tmp_path / "out"
    # Real time (speed-up 1): the mission cannot end before the signal does.
    argv = [sys.executable, "-m", "btcap", "run", str(SMALL), "--out", str(out), "--quiet"]
    proc = subprocess.Popen(
        [*argv, "--speedup", "1"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("running small")
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == code, stderr
    assert "Traceback" not in stderr
    assert f"interrupted by {sig.name}" in stdout
    result = msgspec.json.decode((out / "result.json").read_bytes(), type=MissionResult)
    assert result.interrupted
    assert not result.completed
    assert not result.timed_out
    events = read_record(out / "monitor.jsonl")  # the monitor's page says so too
    (end,) = [e for e in events if e["k"] == "finished"]
    assert end["result"] == "stopped"
    assert end["summary"].endswith("(interrupted)")
