"""Observers, one live process per name and roles, as an operator meets them: ``btcap``
processes with CURVE keys over tcp loopback (free ports), as in docs/deploy.md.

- ``btcap team status --config operator.yaml`` while ``btcap mission run --config
  operator.yaml`` runs (the two commands the docs list) neither takes the operator's place
  nor disturbs its mission;
- a second ``btcap agent`` under a live robot's name is refused, told why and exits 1,
  while the team logs it once; killed and started again elsewhere, the robot rejoins;
- a key with the observer role may look at the team but not run a mission.
"""

from __future__ import annotations

import signal
import subprocess
from contextlib import AsyncExitStack
from pathlib import Path

import anyio
import anyio.abc
import pytest
from agentproc import btcap, free_port, running_agent, stop

from btcap.cli import main

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"
ROLE = {"alpha": "robot", "beta": "robot", "operator": "operator", "eye": "observer"}


class Team:
    """Keys for every name of ROLE, configs on free ports; the robots greet slowly (6 s,
    as a loaded machine takes seconds to start `team status`) so a mission is still
    running when asked about."""

    def __init__(self, tmp_path: Path) -> None:
        self.dir = tmp_path
        self.taken: set[int] = set()
        self.keys = tmp_path / "keys"
        self.keys.mkdir()
        for name, role in ROLE.items():
            assert main(["keys", "new", name, "--role", role, "--dir", str(self.keys)]) == 0
        tree = tmp_path / "slow_tree.yaml"
        tree.write_text(
            "btcap: 1\nname: slow\nroot:\n  type: Sequence\n  name: g\n  children:\n"
            "    - {type: GreetInputs, name: inputs}\n"
            "    - {type: Wait, name: think, options: {seconds: 6}}\n"
            "    - {type: GreetOutputs, name: outputs}\n"
            "wires:\n  - {from: g/inputs.who, to: g/outputs.said}\n"
        )
        self.impl = tmp_path / "slow.yaml"
        self.impl.write_text(
            "btcap_implementation: 1\nname: slow\ninterface: Greet\ntree: slow_tree.yaml\n"
        )
        self.ports = {name: free_port(self.taken) for name in ROLE}
        self.mission = tmp_path / "mission.yaml"
        self.mission.write_text("btcap: 1\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n")

    def config(self, name: str, *, seeds: list[str], file: str | None = None) -> Path:
        """NAME's config (robots implement the slow greeting); ``file`` another file for
        the same name on a port of its own."""
        port = self.ports[name] if file is None else free_port(self.taken)
        seed_lines = "".join(
            f'    - {{robot: {r}, endpoint: "tcp://127.0.0.1:{self.ports[r]}"}}\n' for r in seeds
        )
        path = self.dir / f"{file or name}.yaml"
        path.write_text(
            f"btcap: 1\nrobot: {name}\n"
            f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
            + (f"  implementations: [{self.impl}]\n" if ROLE[name] == "robot" else "")
            + f"network:\n  bind: tcp://127.0.0.1:{port}\n"
            + (f"  seeds:\n{seed_lines}" if seeds else "")
            + "timing: {tick_hz: 20, heartbeat_s: 0.1, failure_timeout_s: 1.0, lease_s: 1.0}\n"
            + f"keys: {{secret: {self.keys / name}.key_secret, trusted: {self.keys}}}\n"
        )
        return path


async def _status(config: Path, *flags: str) -> subprocess.CompletedProcess[bytes]:
    return await anyio.run_process(
        btcap("team", "status", "--config", str(config), *flags), check=False
    )


async def test_status_beside_a_running_mission_from_the_same_config(tmp_path: Path) -> None:
    """The docs' order, with the docs' config: the observer never takes the operator's
    place, so the mission runs to its end on the robot it was first given to."""
    team = Team(tmp_path)
    alpha = team.config("alpha", seeds=[])
    beta = team.config("beta", seeds=["alpha"])
    operator = team.config("operator", seeds=["alpha"])
    with anyio.fail_after(60):
        async with AsyncExitStack() as stack:
            await stack.enter_async_context(running_agent(alpha))
            await stack.enter_async_context(running_agent(beta))
            before = await _status(operator, "--wait", "5")
            assert before.returncode == 0, before.stderr.decode()
            assert "2 member(s)" in before.stdout.decode()
            argv = btcap("mission", "run", str(team.mission), "--config", str(operator))
            mission = await stack.enter_async_context(
                await anyio.open_process([*argv, "--timeout", "30"], stderr=subprocess.PIPE)
            )
            assert mission.stdout is not None
            said = b""
            while b"running on" not in said:
                said += await mission.stdout.receive()
            during = await _status(operator, "--wait", "5")
            shown = during.stdout.decode()
            assert during.returncode == 0, shown + during.stderr.decode()
            assert "(an observer, not a member): 3 member(s)" in shown  # the operator too
            assert "team seen by operator+status-" in shown
            rows = {line.split()[0]: line for line in shown.splitlines()[2:]}
            assert set(rows) == {"alpha", "beta", "operator"}
            assert ":hello#1" in rows["alpha"] + rows["beta"]  # what is running
            async with anyio.create_task_group():
                code = await mission.wait()
            out = said
            while True:
                try:
                    out += await mission.stdout.receive()
                except anyio.EndOfStream:
                    break
    text = out.decode()
    assert code == 0, text
    assert "mission succeeded" in text
    (line,) = [s for s in text.splitlines() if s.startswith("  hello:")]
    assert " -> " not in line  # never re-assigned: the robots never lost the operator


async def test_a_second_live_robot_is_refused_and_a_restarted_one_rejoins(
    tmp_path: Path,
) -> None:
    team = Team(tmp_path)
    alpha = team.config("alpha", seeds=["beta"])
    beta = team.config("beta", seeds=[])
    again = team.config("alpha", seeds=["beta"], file="alpha-again")
    operator = team.config("operator", seeds=["beta"])
    with anyio.fail_after(60):
        async with running_agent(beta, stderr=subprocess.PIPE) as beta_proc:
            async with running_agent(alpha) as alpha_proc:
                assert (await _status(operator, "--wait", "5")).returncode == 0
                second = await anyio.run_process(
                    btcap("agent", str(again)), check=False, stdin=subprocess.DEVNULL
                )
                err = second.stderr.decode()
                assert second.returncode == 1, err
                assert f"alpha is already live at tcp://127.0.0.1:{team.ports['alpha']}" in err
                assert "stop it or use another name" in err
                assert "Traceback" not in err
                shown = (await _status(operator, "--wait", "5")).stdout.decode()
                assert "alpha  " in shown
                alpha_proc.kill()  # dies without a goodbye
                await alpha_proc.wait()
            async with running_agent(again):  # the same robot, started again elsewhere
                with anyio.fail_after(20):
                    while True:
                        after = await _status(operator, "--wait", "3")
                        if after.returncode == 0 and "Greet" in after.stdout.decode():
                            break
                members, _, departed = after.stdout.decode().partition("departed lately")
                rows = members.splitlines()[2:]
                assert sorted(r.split()[0] for r in rows) == ["alpha", "beta"]
                assert "alpha" in departed  # its old life, killed, is listed as failed
            _, beta_err = await stop(beta_proc, signal.SIGTERM)
    taken = [line for line in beta_err.splitlines() if "name_taken" in line]
    assert len(taken) == 1, beta_err  # the team logs it once


async def test_an_observer_key_looks_but_cannot_run_a_mission(tmp_path: Path) -> None:
    team = Team(tmp_path)
    alpha = team.config("alpha", seeds=[])
    eye = team.config("eye", seeds=["alpha"])
    with anyio.fail_after(40):
        async with running_agent(alpha):
            looked = await _status(eye, "--wait", "5")
            assert looked.returncode == 0, looked.stderr.decode()
            assert "team seen by eye+status-" in looked.stdout.decode()
            argv = btcap("mission", "run", str(team.mission), "--config", str(eye))
            ran = await anyio.run_process(argv, check=False)
    err = ran.stderr.decode().strip()
    assert ran.returncode == 2, err
    assert err.count("\n") == 0
    assert "keys.secret: eye's key has the role observer" in err
