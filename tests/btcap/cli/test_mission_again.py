"""The same mission from the same operator config, ten times in a row, against one team.

Each run is a fresh ``btcap mission run`` process (the same operator name on the same
endpoint); the robots are ``btcap agent`` processes that outlive it and remember what they
ran. A restarted operator must mint ids they do not remember (else they decline its awards
as "awarded before" and the mission waits for the 10 s retry), and a clean run logs no
warning (no message dropped for coming before its sender's hello).
"""

from __future__ import annotations

import json
import sys
from contextlib import AsyncExitStack
from pathlib import Path

import anyio
import anyio.abc
import pytest
from agentproc import free_port, running_agent

from btcap.cli import main

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"
TEAM = ROOT / "examples" / "team"
ROBOTS = ("alpha", "beta", "gamma")
RUNS = 10


def _config(tmp_path: Path, robot: str, ports: dict[str, int], *, impl: bool) -> Path:
    """A robot on a fixed loopback port with CURVE keys, as in examples/team: the operator
    knows only alpha (it learns the others from alpha's roster, and they may speak first);
    retry_s (10 s) far beyond a run, so a declined first auction would show."""
    known = ["alpha"] if robot == "operator" else [r for r in ROBOTS if r != robot]
    seeds = "".join(
        f'    - {{robot: {r}, endpoint: "tcp://127.0.0.1:{ports[r]}"}}\n' for r in known
    )
    keys = tmp_path / "keys"
    path = tmp_path / f"{robot}.yaml"
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
        + (f"  implementations: [{CAPS / 'greet.yaml'}]\n" if impl else "")
        + f"network:\n  bind: tcp://127.0.0.1:{ports[robot]}\n  seeds:\n{seeds}"
        + "timing: {tick_hz: 20, heartbeat_s: 0.1, failure_timeout_s: 1.0, lease_s: 1.0}\n"
        + f"keys: {{secret: {keys / robot}.key_secret, trusted: {keys}}}\n"
    )
    return path


async def test_the_same_mission_runs_ten_times_from_a_fresh_operator(tmp_path: Path) -> None:
    taken: set[int] = set()
    ports = {r: free_port(taken) for r in (*ROBOTS, "operator")}
    (tmp_path / "keys").mkdir()
    for robot in ports:
        role = "operator" if robot == "operator" else "robot"
        assert main(["keys", "new", robot, "--role", role, "--dir", str(tmp_path / "keys")]) == 0
    configs = {r: _config(tmp_path, r, ports, impl=True) for r in ROBOTS}
    operator = _config(tmp_path, "operator", ports, impl=False)
    argv = [sys.executable, "-m", "btcap", "--log-level", "info", "--log-json", "mission", "run"]
    argv += [str(TEAM / "mission.yaml"), "--config", str(operator), "--timeout", "30"]
    with anyio.fail_after(240):
        async with AsyncExitStack() as stack:
            for robot in ROBOTS:
                await stack.enter_async_context(running_agent(configs[robot]))
            for run in range(RUNS):
                with anyio.fail_after(40):
                    done = await anyio.run_process(argv, check=False)
                out, err = done.stdout.decode(), done.stderr.decode()
                assert done.returncode == 0, (run, out, err)
                assert "mission succeeded" in out, (run, out)
                events = [json.loads(line) for line in err.splitlines() if line.startswith("{")]
                # None declined as awarded before (an id of the last operator's life) ...
                declined = [e for e in events if e.get("event") == "auction.award_declined"]
                assert not [e for e in declined if "awarded before" in e["reason"]], (run, err)
                # ... so each greeting went to one robot by its first auction, no retry.
                summary = [line for line in out.splitlines() if line.startswith("  greetings/")]
                assert len(summary) == 3, (run, out)
                assert all(" succeeded on " in s and " -> " not in s for s in summary), out
                # A clean run warns about nothing (e.g. messages dropped before a hello).
                loud = [e for e in events if e.get("level") in ("warning", "error", "critical")]
                assert loud == [], (run, loud)
