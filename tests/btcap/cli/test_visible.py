"""Failures and refusals a person sees at the default log level: a refused key on both
machines, a robot that never joined, a failed robot in ``team status`` and in a
mission's output. Agents in their own processes, on loopback tcp (ports the system
chooses) or ipc, always stopped and reaped."""

from __future__ import annotations

import shutil
import signal
import subprocess
from pathlib import Path

import anyio
import pytest
from agentproc import btcap, listening_agent, running_agent, said_on_stderr, stop

from btcap.bt.registry import default_registry
from btcap.cli import main
from btcap.team.deployment.agentconfig import load_agent_file
from btcap.team.deployment.deploy import open_agent, run_mission_file, wait_for_team
from btcap.transports import KeyPair
from btcap.transports.refusals import fingerprint
from btcap.transports.security import write_key_pair

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"


def _keyed(tmp_path: Path, robot: str, trusted: str, seeds: dict[str, str]) -> Path:
    """A robot with keys on a loopback tcp port of the system's choosing."""
    seed_lines = "".join(f'    - {{robot: {r}, endpoint: "{e}"}}\n' for r, e in seeds.items())
    path = tmp_path / f"{robot}.yaml"
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
        "network:\n  bind: tcp://127.0.0.1:*\n"
        + (f"  seeds:\n{seed_lines}" if seeds else "")
        + f"keys: {{secret: {tmp_path / robot}.key_secret, trusted: {tmp_path / trusted}}}\n"
        "timing: {heartbeat_s: 0.1, failure_timeout_s: 1.0}\n"
    )
    return path


@pytest.mark.slow
async def test_a_refused_key_is_told_on_both_machines_and_the_robot_never_joined(
    tmp_path: Path,
) -> None:
    """beta's key is not in alpha's trusted folder: beta says so within seconds (and at
    info, that it has not joined yet), alpha says whose address and which key it
    refused, and beta's Ctrl-C line does not claim it was in the team."""
    for folder in ("team", "betas"):
        (tmp_path / folder).mkdir()
    for robot in ("alpha", "beta"):
        public, _ = write_key_pair(tmp_path, robot)
        shutil.copy(public, tmp_path / "betas")
    shutil.copy(tmp_path / "alpha.key", tmp_path / "team")
    alpha_file = _keyed(tmp_path, "alpha", "team", {})
    with anyio.fail_after(30):
        async with listening_agent(alpha_file, stderr=subprocess.PIPE) as (alpha, endpoint):
            beta_file = _keyed(tmp_path, "beta", "betas", {"alpha": endpoint})
            beta_run = listening_agent(beta_file, stderr=subprocess.PIPE, log_level="info")
            async with beta_run as (beta, _):
                with anyio.fail_after(5):
                    said = await said_on_stderr(beta, "alpha refused our key")
                with anyio.fail_after(5):  # after twice the failure timeout (1 s)
                    said = await said_on_stderr(beta, "agent.not_joined", said)
                code, rest = await stop(beta, signal.SIGINT)
            with anyio.fail_after(5):
                refused = await said_on_stderr(alpha, "transport.key_refused")
            await stop(alpha, signal.SIGINT)
    beta_said = said.decode() + rest
    assert code == 128 + signal.SIGINT
    assert "[warning  ] transport.handshake_refused" in beta_said
    why = "alpha refused our key: is beta.key in its trusted folder (keys.trusted in alpha's"
    assert why in beta_said
    assert "leaving the team" not in beta_said
    assert f"btcap: SIGINT, stopping, never joined the team: {why}" in beta_said
    waiting = next(x for x in beta_said.splitlines() if "agent.not_joined" in x)
    assert "[info     ]" in waiting
    assert why in waiting
    line = next(x for x in refused.decode().splitlines() if "transport.key_refused" in x)
    assert "[warning  ]" in line
    assert "address=127.0.0.1" in line
    assert fingerprint(KeyPair.load(tmp_path / "beta.key_secret").public) in line
    assert "known_as=unknown" in line


def test_a_silent_seed_is_told_with_where_it_was_looked_for(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    operator = _robot(tmp_path, "operator", cost=None, seeds=["ghost"])
    assert main(["team", "status", "--config", str(operator), "--wait", "0.3"]) == 1
    err = capsys.readouterr().err
    where = f"ghost at ipc://{tmp_path}/ghost.sock in network.seeds"
    assert f"seed ghost did not answer within 0.3 s: is it up ({where}), or is --wait" in err


def _robot(tmp_path: Path, robot: str, *, cost: float | None, seeds: list[str]) -> Path:
    """A robot on an ipc socket that greets in 2 s at ``cost`` (None: it cannot); a
    silent robot is declared failed after 1 s, long before a 10 s lease lapses (the
    lease, not the failure, decides when the next run of a killed robot's task may
    start: docs/concepts.md, the fence; so no longer than the failure needs)."""
    impl = ""
    if cost is not None:
        tree = tmp_path / f"{robot}-tree.yaml"
        tree.write_text(
            "btcap: 1\nname: slow\nroot:\n  type: Sequence\n  name: g\n  children:\n"
            "    - {type: GreetInputs, name: inputs}\n"
            "    - {type: Wait, name: think, options: {seconds: 2.0}}\n"
            "    - {type: GreetOutputs, name: outputs}\n"
            "wires:\n  - {from: g/inputs.who, to: g/outputs.said}\n"
        )
        (tmp_path / f"{robot}-greet.yaml").write_text(
            f"btcap_implementation: 1\nname: {robot}-greet\ninterface: Greet\n"
            f"tree: {tree.name}\ncost: {cost}\n"
        )
        impl = f"  implementations: [{tmp_path / robot}-greet.yaml]\n"
    seed_lines = "".join(
        f'    - {{robot: {r}, endpoint: "ipc://{tmp_path}/{r}.sock"}}\n' for r in seeds
    )
    path = tmp_path / f"{robot}.yaml"
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n{impl}"
        f"network:\n  bind: ipc://{tmp_path}/{robot}.sock\n"
        + (f"  seeds:\n{seed_lines}" if seeds else "")
        + "timing: {tick_hz: 20, heartbeat_s: 0.1, failure_timeout_s: 1.0, lease_s: 10,"
        " keepalive_s: 0.2}\n"
    )
    return path


@pytest.mark.slow
async def test_a_killed_robot_is_told_in_the_mission_output_and_in_team_status(
    tmp_path: Path,
) -> None:
    """beta (the cheaper) runs the greeting and is killed: the mission's output says why
    the work moves, the survivor's log warns once, and ``team status`` lists beta as
    failed, with when and why."""
    alpha = _robot(tmp_path, "alpha", cost=5.0, seeds=[])
    beta = _robot(tmp_path, "beta", cost=1.0, seeds=["alpha"])
    operator = _robot(tmp_path, "operator", cost=None, seeds=["alpha", "beta"])
    observer = _robot(tmp_path, "observer", cost=None, seeds=["alpha"])
    mission = tmp_path / "mission.yaml"
    mission.write_text("btcap: 1\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n")
    registry = default_registry(plugins=False)
    lines: list[str] = []
    with anyio.fail_after(60):
        async with (
            running_agent(alpha, stderr=subprocess.PIPE) as alpha_proc,
            running_agent(beta) as beta_proc,
        ):
            async with open_agent(load_agent_file(operator), registry) as agent:
                assert await wait_for_team(agent, ["alpha", "beta"], timeout_s=10)

                def progress(line: str) -> None:
                    lines.append(line)
                    if "running on beta" in line:
                        beta_proc.kill()

                report = await run_mission_file(agent, mission, registry, progress=progress)
            status = await anyio.run_process(
                btcap("team", "status", "--config", str(observer), "--wait", "3"), check=False
            )
            _, alpha_said = await stop(alpha_proc, signal.SIGINT)
    assert report.succeeded
    assert report.capabilities[0].robots == ["beta", "alpha"]
    said = [line.split(" s  ", 1)[1] for line in lines]
    moved = said.index("hello: beta failed — re-auctioning Greet")
    assert "hello: running on beta" in said[:moved]
    assert said[moved + 1] == "hello: assigned on alpha", "not 'unassigned on beta'"
    assert "hello: succeeded on alpha" in said[moved:]
    failed = [x for x in alpha_said.splitlines() if "team.member_failed" in x]
    assert len(failed) == 1, alpha_said
    assert "[warning  ]" in failed[0]
    assert "member=beta" in failed[0]
    shown = status.stdout.decode()
    assert status.returncode == 0, status.stderr.decode()
    departed = shown.split("departed lately: ", 1)[1].splitlines()
    assert departed[1].split()[:2] == ["robot", "what"]
    row = next(r for r in departed if r.startswith("beta "))
    assert row.split()[1] == "failed"
    assert " s ago)" in row
    assert row.endswith("stopped answering probes (suspected, not refuted)")
