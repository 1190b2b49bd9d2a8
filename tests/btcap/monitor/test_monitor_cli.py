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


async def test_agent_and_mission_run_record_mcap(tmp_path: Path) -> None:
    """``--record FILE.mcap`` on both robot commands: each file is whole once its
    command ends, with its robot's runs and the team as that robot saw them."""
    from btcap.monitor.record import read_metadata, read_recording

    robot = _config(tmp_path, "ada", impl=True, seed=None)
    operator = _config(tmp_path, "operator", impl=False, seed="ada")
    mission = tmp_path / "mission.yaml"
    mission.write_text(
        "btcap: 1\nname: hello\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n"
    )
    agent_file, mission_file = tmp_path / "ada.mcap", tmp_path / "mission.mcap"
    argv = [sys.executable, "-m", "btcap", "agent", str(robot), "--until-stdin-closes"]
    with anyio.fail_after(60):
        proc = await anyio.open_process(
            [*argv, "--record", str(agent_file)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        try:
            assert proc.stdout is not None
            assert proc.stdin is not None
            said = b""
            while b"listening" not in said:
                said += await proc.stdout.receive()
            run = ["mission", "run", str(mission), "--config", str(operator)]
            done = await anyio.run_process(
                [*argv[:3], *run, "--record", str(mission_file)], check=False
            )
            assert done.returncode == 0, done.stderr.decode()
            await proc.stdin.aclose()  # the agent leaves and closes its recording
            assert await proc.wait() == 0
        finally:
            with anyio.CancelScope(shield=True):
                if proc.returncode is None:
                    proc.kill()
                await proc.aclose()
    for path, me in ((agent_file, "ada"), (mission_file, "operator")):
        events, cut = read_recording(path)
        assert cut is None, cut
        assert read_metadata(path)["robot"] == me
        joined = {e["robot"] for e in events if e["k"] == "team" and e["change"] == "joined"}
        assert joined == {"ada", "operator"}
        assert events[-1]["k"] == "finished"
    agent_events = read_recording(agent_file)[0]
    assert ("ada", "ada-host") in {
        (e["robot"], e["tree"]) for e in agent_events if e["k"] == "tree"
    }
    changes = [(e["robot"], e["change"]) for e in agent_events if e["k"] == "team"]
    assert changes[-1] == ("operator", "left")  # as the agent saw the mission end
    runs = [e for e in read_recording(mission_file)[0] if e["k"] == "run"]
    assert [(e["phase"], e.get("robot")) for e in runs] == [("start", "ada"), ("end", None)]
    assert runs[0]["capability"] == "Greet"
    assert runs[1]["result"] == "succeeded"
    hosted = [e for e in agent_events if e["k"] == "run"]  # the same run, as ada ran it
    assert [(e["phase"], e["execution"]) for e in hosted] == [
        ("start", runs[0]["execution"]),
        ("end", runs[0]["execution"]),
    ]
    assert (hosted[0]["origin"], hosted[1]["result"]) == ("operator", "succeeded")
