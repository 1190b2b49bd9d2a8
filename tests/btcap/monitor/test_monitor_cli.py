"""``--monitor`` on the robot commands: ``btcap agent`` serves its robot's picture while
``btcap mission run`` (with a monitor of its own) runs a mission on it, over ipc."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import aiohttp
import anyio

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"


def _config(tmp_path: Path, robot: str, *, impl: bool, seed: str | None) -> Path:
    path = tmp_path / f"{robot}.yaml"
    seeds = f'  seeds:\n    - {{robot: {seed}, endpoint: "ipc://{tmp_path}/{seed}.sock"}}\n'
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
        + (f"  implementations: [{CAPS / 'greet.yaml'}]\n" if impl else "")
        + f"network:\n  bind: ipc://{tmp_path}/{robot}.sock\n"
        + (seeds if seed else "")
        + "timing: {tick_hz: 20, heartbeat_s: 0.1, failure_timeout_s: 30,"
        " lease_s: 30, keepalive_s: 0.2}\n"
    )
    return path


async def test_agent_and_mission_run_serve_the_monitor(tmp_path: Path) -> None:
    robot = _config(tmp_path, "ada", impl=True, seed=None)
    operator = _config(tmp_path, "operator", impl=False, seed="ada")
    mission = tmp_path / "mission.yaml"
    mission.write_text(
        "btcap: 1\nname: hello\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n"
    )
    argv = [sys.executable, "-m", "btcap", "agent", str(robot), "--monitor", "127.0.0.1:0"]
    with anyio.fail_after(60):
        proc = await anyio.open_process(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        try:
            assert proc.stdout is not None
            said = b""
            while b"listening" not in said or b"monitor: " not in said:
                said += await proc.stdout.receive()
            url = said.split(b"monitor: ", 1)[1].split()[0].decode()
            run = ["mission", "run", str(mission), "--config", str(operator)]
            done = await anyio.run_process(
                [*argv[:3], *run, "--monitor", "127.0.0.1:0"], check=False
            )
            assert done.returncode == 0, done.stderr.decode()
            assert b"monitor: http://127.0.0.1:" in done.stdout
            async with aiohttp.ClientSession() as http, http.get(url + "api/state") as resp:
                state: dict[str, Any] = await resp.json()
        finally:
            with anyio.CancelScope(shield=True):
                proc.kill()
                await proc.aclose()
    assert state["robots"]["ada"]["status"] == "joined"
    assert "ada-host" in state["robots"]["ada"]["trees"]
    assert state["robots"]["operator"]["status"] in ("joined", "left")  # it said goodbye
    assert ("operator", "joined") in {(m["robot"], m["change"]) for m in state["marks"]}
