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
from agentproc import listening_agent, said_on_stderr, stop

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
    """beta's key is not in alpha's trusted folder: beta says so within seconds, alpha
    says whose address and which key it refused, and beta's Ctrl-C line does not claim
    it was in the team."""
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
            async with listening_agent(beta_file, stderr=subprocess.PIPE) as (beta, _):
                with anyio.fail_after(5):
                    said = await said_on_stderr(beta, "alpha refused our key")
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
    line = next(x for x in refused.decode().splitlines() if "transport.key_refused" in x)
    assert "[warning  ]" in line
    assert "address=127.0.0.1" in line
    assert fingerprint(KeyPair.load(tmp_path / "beta.key_secret").public) in line
    assert "known_as=unknown" in line
