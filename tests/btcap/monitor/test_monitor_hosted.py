"""An agent's recording holds every run it hosted, however short: a run taken up and
put down between two of the monitor's batches (a Greet is done in one tick, well
within the 50 ms between batches) is there with its start, its end and its result,
in JSON Lines and in MCAP. Two robots on tcp loopback, their clocks sped up."""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcap.reader import make_reader

from btcap.bt.registry import default_registry
from btcap.monitor.channels import EVENT_TOPICS
from btcap.monitor.monitor import Monitor
from btcap.monitor.record import read_recording
from btcap.team.deployment.agentconfig import load_agent_file
from btcap.team.deployment.deploy import open_agent, run_mission_file, wait_for_team

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"
#: Auction windows, heartbeats and leases pass ten times faster than the wall.
TIMING = "timing: {speedup: 10, tick_hz: 20, lease_s: 30, keepalive_s: 0.2}\n"


def _config(tmp_path: Path, robot: str, *, seed: str | None) -> Path:
    path = tmp_path / f"{robot}.yaml"
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
        + ("" if seed else f"  implementations: [{CAPS / 'greet.yaml'}]\n")
        + "network:\n  bind: tcp://127.0.0.1:*\n"
        + (f'  seeds:\n    - {{robot: ada, endpoint: "{seed}"}}\n' if seed else "")
        + TIMING
    )
    return path


async def _hosted_run(tmp_path: Path, record: Path, *, both: bool = False) -> None:
    """``ada`` hosts one Greet for ``operator``'s mission, recorded as ``btcap agent
    --record`` records it (a monitor that serves nothing, given the agent); ``both``:
    the same monitor watches the operator and its mission tree too (as ``btcap run``)."""
    registry = default_registry(plugins=False)
    mission = tmp_path / "mission.yaml"
    mission.write_text("btcap: 1\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n")
    ada = load_agent_file(_config(tmp_path, "ada", seed=None))
    async with (
        open_agent(ada, registry) as agent,
        Monitor(port=None, record=record, title="ada", metadata={"robot": "ada"}) as monitor,
    ):
        monitor.add_agent(agent)
        endpoint = agent.system.transport.endpoint  # type: ignore[attr-defined]
        operator = load_agent_file(_config(tmp_path, "operator", seed=endpoint))
        async with open_agent(operator, registry) as origin:
            assert await wait_for_team(origin, ["ada"], timeout_s=10)
            shown = functools.partial(monitor.add_tree, robot="operator") if both else None
            if both:
                monitor.add_agent(origin)
            report = await run_mission_file(origin, mission, registry, on_tree=shown)
        assert report.succeeded
        assert report.capabilities[0].robots == ["ada"]


@pytest.mark.parametrize("suffix", ["jsonl", "mcap"])
async def test_an_agent_records_a_run_shorter_than_a_batch(tmp_path: Path, suffix: str) -> None:
    record = tmp_path / f"ada.{suffix}"
    with anyio.fail_after(30):
        await _hosted_run(tmp_path, record)
    events, cut = read_recording(record)
    assert cut is None, cut
    runs = [e for e in events if e["k"] == "run"]
    assert [e["phase"] for e in runs] == ["start", "end"]
    start, end = runs
    assert start["execution"] == end["execution"]
    assert start["execution"].startswith("operator")
    assert start["execution"].endswith(":hello#1")
    assert (start["robot"], start["origin"]) == ("ada", "operator")
    assert (start["node"], start["capability"]) == ("hello", "Greet")
    assert end["result"] == "succeeded"
    assert start["t"] <= end["t"]
    if suffix == "mcap":  # the same, as any MCAP reader sees it
        topic = EVENT_TOPICS["run"][0]
        with record.open("rb") as f:
            held: list[dict[str, Any]] = [
                json.loads(m.data)
                for _, ch, m in make_reader(f).iter_messages(topics=[topic])
                if ch.topic == topic
            ]
        assert [(e["phase"], e["execution"]) for e in held] == [
            ("start", start["execution"]),
            ("end", start["execution"]),
        ]
        assert held[1]["result"] == "succeeded"


async def test_a_run_seen_from_both_ends_is_recorded_once(tmp_path: Path) -> None:
    """A monitor that watches the capability node as well as the robot running it
    records the run once, as the node reports it."""
    record = tmp_path / "both.jsonl"
    with anyio.fail_after(30):
        await _hosted_run(tmp_path, record, both=True)
    runs = [e for e in read_recording(record)[0] if e["k"] == "run"]
    assert [(e["phase"], e.get("robot")) for e in runs] == [("start", "ada"), ("end", None)]
    assert runs[1]["result"] == "succeeded"
    assert "operator" in {e["robot"] for e in read_recording(record)[0] if e["k"] == "tree"}
