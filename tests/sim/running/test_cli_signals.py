"""``btcap run`` stopped by SIGTERM or SIGINT ends the mission early and still writes its
result, marked interrupted (its recording too), and exits with 128 + the signal's number."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import msgspec
import pytest

from btcap.monitor import read_record
from btcap.sim.running.metrics import MissionResult

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"

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


def _read_until(proc: subprocess.Popen[bytes], text: str, timeout: float) -> str:
    """What ``proc`` wrote on stderr up to and including ``text``."""
    assert proc.stderr is not None
    fd = proc.stderr.fileno()
    seen = ""
    deadline = time.monotonic() + timeout
    while text not in seen:
        left = deadline - time.monotonic()
        ready = select.select([fd], [], [], left)[0] if left > 0 else []
        assert ready, f"no {text!r} within {timeout} s; stderr so far:\n{seen}"
        chunk = os.read(fd, 65536)
        assert chunk, f"exited before {text!r}; stderr:\n{seen}"
        seen += chunk.decode(errors="replace")
    return seen


def _processes_mentioning(text: str) -> dict[int, str]:
    """The running processes whose command lines contain ``text``, by pid."""
    found = {}
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            argv = cmdline.read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # it ended while we looked
            continue
        if text in argv:
            found[int(cmdline.parent.name)] = argv
    return found


@pytest.mark.skipif(not Path("/proc/self/cmdline").exists(), reason="needs Linux /proc")
def test_ctrl_c_while_distributed_robots_start_exits_cleanly_and_leaves_no_process(
    tmp_path: Path,
) -> None:
    """Ctrl-C at a terminal signals the whole foreground process group: once the first
    robot process listens (the others still starting), one SIGINT to the group. The run
    ends as any interrupted run does, with no traceback from it or its robots, and every
    robot process is gone when it exits."""
    robots_dir = tmp_path / "robots"  # robots' configs, so their command lines, are here
    robots_dir.mkdir()
    argv = [sys.executable, "-m", "btcap", "--log-level", "info", "run", str(SMALL)]
    proc = subprocess.Popen(
        [*argv, "--distributed", "--speedup", "1", "--quiet", "--out", str(tmp_path / "out")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=dict(os.environ, TMPDIR=str(robots_dir)),
        start_new_session=True,  # a process group of its own, as a shell's job
    )
    try:
        early = _read_until(proc, "sim.robot_up", timeout=60)
        robots = _processes_mentioning(str(robots_dir))
        assert robots  # the check can see robots
        # The terminal's SIGINT is for the run alone, which stops its robots itself.
        assert [pid for pid in robots if os.getpgid(pid) == proc.pid] == []
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    err = early + stderr.decode(errors="replace")
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert [line for line in err.splitlines() if line.startswith("btcap:")] == []  # robots
    assert "interrupted by SIGINT" in stdout.decode()
    assert _processes_mentioning(str(robots_dir)) == {}
    result = msgspec.json.decode(
        (tmp_path / "out" / "result.json").read_bytes(), type=MissionResult
    )
    assert result.interrupted
    assert result.errors == []  # no robot went down on its own
