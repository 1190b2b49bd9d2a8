"""``python -m btcap.bench.allocation.team_runs [--runs 20]``: run
``examples/team/run-local.sh`` over and over, with its own timing (failure_timeout_s
1.0), and count the robots' false failure reports: ``team.member_failed`` lines logged
while every member was alive (each run's team lives until its mission has ended). A
stalled event loop (a robot's or the operator's) shows here as a member declared failed
that was not.

Not a ratio benchmark (it is not in ``python -m btcap.bench all``): a count over runs,
written to ``bench/results/team_runs.json``. ``--btcap CMD`` runs another install's
command (to count before and after a change in one sitting).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from btcap.bench.common import write_result

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "examples" / "team" / "run-local.sh"
_STAMP = re.compile(r"^(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d+Z?)")
_FIRST = re.compile(r"^\s*([\d.]+) s\s+\S+: assigned on ")


def _stamp(line: str) -> float | None:
    m = _STAMP.match(line)
    if m is None:
        return None
    text = m.group(1).rstrip("Z")
    return datetime.fromisoformat(text).replace(tzinfo=UTC).timestamp()


def one_run(btcap: str | None, logs: Path) -> dict[str, Any]:
    """One run of the example: whether the mission succeeded, when its first task was
    assigned (mission seconds), and the robots' member_failed lines before its end."""
    env = dict(os.environ, BTCAP_TEAM_LOGS=str(logs))
    if btcap:
        env["BTCAP"] = btcap
    proc = subprocess.Popen(
        ["bash", str(SCRIPT)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env
    )
    assert proc.stdout is not None
    ended: float | None = None
    first: float | None = None
    said: list[str] = []
    for line in proc.stdout:
        said.append(line)
        if first is None and (m := _FIRST.match(line)):
            first = float(m.group(1))
        if line.startswith("mission ") and ended is None:
            ended = time.time()
    code = proc.wait()
    failed: list[str] = []
    for log in sorted(logs.glob("*.log")):
        for line in log.read_text(errors="replace").splitlines():
            at = _stamp(line)
            if "team.member_failed" in line and (ended is None or at is None or at <= ended):
                failed.append(f"{log.stem}: {line.strip()}")
    return {
        "succeeded": code == 0,
        "first_assigned_s": first,
        "false_failures": failed,
        "output": "".join(said) if code != 0 else "",
    }


def main(argv: Sequence[str] | None = None, *, quick: bool = False) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m btcap.bench.allocation.team_runs", description=__doc__
    )
    parser.add_argument("--runs", type=int, default=3 if quick else 20)
    parser.add_argument("--btcap", help="the btcap command to run (default: this install's)")
    args = parser.parse_args(argv)
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="btcap-team-runs.") as tmp:
        for i in range(args.runs):
            run = one_run(args.btcap, Path(tmp) / str(i))
            runs.append(run)
            fails = run["false_failures"]
            print(
                f"run {i + 1}/{args.runs}: mission {'ok' if run['succeeded'] else 'FAILED'}, "
                f"first assignment at {run['first_assigned_s']} s, "
                f"{len(fails)} member_failed of a live member",
                flush=True,
            )
            for line in fails:
                print(f"    {line}", flush=True)
    total = sum(len(r["false_failures"]) for r in runs)
    hit = sum(1 for r in runs if r["false_failures"])
    ok = sum(1 for r in runs if r["succeeded"])
    firsts = sorted(r["first_assigned_s"] for r in runs if r["first_assigned_s"] is not None)
    print(
        f"{args.runs} runs: {ok} missions succeeded; {total} member_failed lines of live "
        f"members, in {hit} runs; first assignment {firsts[0] if firsts else '-'}"
        f"-{firsts[-1] if firsts else '-'} s"
    )
    write_result("team_runs", {"runs": runs, "false_failures": total, "runs_with": hit})
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
