"""``btcap agent``, ``btcap team status`` and ``btcap mission run``, on loopback only."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import anyio
import anyio.abc
import pytest
from agentproc import btcap, running_agent, stop

from btcap.bt.registry import default_registry
from btcap.cli import main
from btcap.team.deployment.agentconfig import load_agent_file
from btcap.team.deployment.deploy import open_agent, run_mission_file, wait_for_team
from btcap.team.deployment.spawn import AsyncAgentProcess

ROOT = Path(__file__).resolve().parents[3]
CAPS = ROOT / "examples" / "capabilities"
TEAM = ROOT / "examples" / "team"


def _config(tmp_path: Path, robot: str, *, impl: Path | None, seeds: list[str]) -> Path:
    """A robot on an ipc socket in ``tmp_path``; long leases and failure timeouts, so only
    a goodbye can explain a quick re-assignment."""
    seed_lines = "".join(
        f'    - {{robot: {r}, endpoint: "ipc://{tmp_path}/{r}.sock"}}\n' for r in seeds
    )
    path = tmp_path / f"{robot}.yaml"
    path.write_text(
        f"btcap: 1\nrobot: {robot}\n"
        f"capabilities:\n  interfaces: [{CAPS / 'interfaces.yaml'}]\n"
        + (f"  implementations: [{impl}]\n" if impl else "")
        + f"network:\n  bind: ipc://{tmp_path}/{robot}.sock\n"
        + (f"  seeds:\n{seed_lines}" if seeds else "")
        + "timing: {tick_hz: 20, heartbeat_s: 0.1, failure_timeout_s: 30,"
        " lease_s: 30, keepalive_s: 0.2}\n"
    )
    return path


def _slow_greet(tmp_path: Path, name: str, cost: float) -> Path:
    tree = tmp_path / f"{name}_tree.yaml"
    tree.write_text(
        "btcap: 1\nname: slow\nroot:\n  type: Sequence\n  name: g\n  children:\n"
        "    - {type: GreetInputs, name: inputs}\n"
        "    - {type: Wait, name: think, options: {seconds: 2.0}}\n"
        "    - {type: GreetOutputs, name: outputs}\n"
        "wires:\n  - {from: g/inputs.who, to: g/outputs.said}\n"
    )
    impl = tmp_path / f"{name}.yaml"
    impl.write_text(
        f"btcap_implementation: 1\nname: {name}\ninterface: Greet\n"
        f"tree: {tree.name}\ncost: {cost}\n"
    )
    return impl


def test_bad_config_exits_2_naming_the_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("btcap: 1\nrobot: r\ntiming: {tick_hz: -1}\n")
    for argv in (["agent", str(path)], ["team", "status", "--config", str(path)]):
        assert main(argv) == 2
        assert f"{path}: timing.tick_hz" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ("timing: {tick_hz: .inf}", "timing.tick_hz: expected a finite number, got inf"),
        ("timing: {speedup: .nan}", "timing.speedup: Expected `float` > 0.0"),
        ("timing: {heartbeat_fanout: 0}", "timing.heartbeat_fanout: Expected `int` >= 1"),
        ("network: {max_peers: 0}", "network.max_peers: Expected `int` >= 1"),
        (
            "allocation: {strategy: cheapest}",
            "allocation.strategy: allocation strategy 'cheapest': expected one of auction, ",
        ),
        ("allocation: {move_margin: 1}", "allocation.move_margin: Expected `float` < 1.0"),
        ("plugin: {factory: pkg.mod:make, args: {limit: .inf}}", "plugin.args.limit: expected"),
    ],
)
def test_every_command_reading_an_agent_file_refuses_a_bad_value_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, field: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(f"btcap: 1\nrobot: r\n{body}\n")
    for argv in (
        ["agent", str(path)],
        ["team", "status", "--config", str(path)],
        ["mission", "run", str(tmp_path / "tree.yaml"), "--config", str(path)],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"btcap: error: {path}: {field}"), err
        assert err.count("\n") == 1, err


def test_agent_refuses_a_bind_beyond_this_host_without_keys(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "open.yaml"
    path.write_text(
        "btcap: 1\nrobot: r\nnetwork: {bind: 'tcp://0.0.0.0:7000', advertise: "
        "'tcp://192.0.2.1:7000'}\n"
    )
    assert main(["agent", str(path)]) == 2
    assert "network.bind" in capsys.readouterr().err


def test_alone_status_fails_and_a_mission_stops_once_no_seed_answered(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    operator = _config(tmp_path, "operator", impl=None, seeds=["ghost"])
    assert main(["team", "status", "--config", str(operator), "--wait", "0.3"]) == 1
    out = capsys.readouterr()
    assert "0 member(s)" in out.out
    assert "seed ghost did not answer" in out.err
    mission = ["mission", "run", str(TEAM / "mission.yaml"), "--config", str(operator)]
    # Not the whole --timeout of a mission nobody can take: it stops after --wait.
    assert main([*mission, "--wait", "0.2", "--timeout", "5"]) == 1
    out = capsys.readouterr()
    where = f"ghost at ipc://{tmp_path}/ghost.sock in network.seeds"
    assert out.err == (
        "btcap: error: no seed answered within 0.2 s, so the mission was not started: "
        f"is it up ({where}), or is --wait too short?\n"
    )
    assert "mission" not in out.out


def test_a_robot_without_seeds_runs_its_mission_alone_until_it_times_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    operator = _config(tmp_path, "operator", impl=None, seeds=[])
    mission = ["mission", "run", str(TEAM / "mission.yaml"), "--config", str(operator)]
    assert main([*mission, "--wait", "0.2", "--timeout", "0.5"]) == 1
    out = capsys.readouterr().out
    assert "operator has no teammates: nobody answered" in out
    assert "mission timed out" in out
    assert "greetings/ada: unassigned on nobody" in out


def test_a_bad_mission_tree_fails_before_joining(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    operator = _config(tmp_path, "operator", impl=None, seeds=[])
    tree = tmp_path / "tree.yaml"
    tree.write_text("btcap: 1\nroot: {type: Greeet, name: g}\n")
    assert main(["mission", "run", str(tree), "--config", str(operator)]) == 1
    assert "Greeet" in capsys.readouterr().err
    assert main(["mission", "run", str(tmp_path / "none.yaml"), "--config", str(operator)]) == 2


@pytest.mark.slow
async def test_a_stopped_agent_says_goodbye_and_its_work_moves_at_once(tmp_path: Path) -> None:
    """SIGTERM on the executor: the origin re-assigns without waiting for the 30 s lease
    or failure timeout, because the agent left the team with a goodbye."""
    cheap = _config(tmp_path, "cheap", impl=_slow_greet(tmp_path, "cheap-greet", 1.0), seeds=[])
    dear = _config(tmp_path, "dear", impl=_slow_greet(tmp_path, "dear-greet", 5.0), seeds=[])
    operator = _config(tmp_path, "operator", impl=None, seeds=["cheap", "dear"])
    mission = tmp_path / "mission.yaml"
    mission.write_text("btcap: 1\nroot: {type: Greet, name: hello, inputs: {who: Ada}}\n")
    registry = default_registry(plugins=False)
    with anyio.fail_after(40):
        async with running_agent(cheap) as cheap_proc, running_agent(dear):
            status = await anyio.run_process(
                btcap("team", "status", "--config", str(operator), "--wait", "5"), check=False
            )
            shown = status.stdout.decode()
            assert status.returncode == 0, status.stderr.decode()
            assert "2 member(s)" in shown
            assert {"cheap", "dear", "Greet"} <= set(shown.split())

            config = load_agent_file(operator)
            async with open_agent(config, registry) as agent:
                assert await wait_for_team(agent, ["cheap", "dear"], timeout_s=10)

                def progress(line: str) -> None:
                    if "running on cheap" in line:
                        cheap_proc.send_signal(signal.SIGTERM)

                report = await run_mission_file(agent, mission, registry, progress=progress)
            assert await cheap_proc.wait() == 128 + signal.SIGTERM  # it stopped cleanly
    assert report.succeeded
    (hello,) = report.capabilities
    assert hello.robots == ["cheap", "dear"]
    assert hello.outputs == {"said": "Ada"}
    assert report.elapsed_s < 10  # the dear robot's 2 s of work, not a 30 s timeout


@pytest.mark.slow
def test_the_example_team_script_runs_its_mission() -> None:
    env = dict(os.environ, BTCAP=f"{sys.executable} -m btcap")
    done = subprocess.run(
        ["bash", str(TEAM / "run-local.sh")],
        capture_output=True,
        env=env,
        timeout=120,
        check=False,
    )
    out = done.stdout.decode()
    assert done.returncode == 0, out + done.stderr.decode()
    assert "mission succeeded" in out
    for robot in ("alpha", "beta", "gamma"):
        assert f"agent {robot} listening on tcp://127.0.0." in out


@pytest.mark.slow
async def test_a_supervised_agent_leaves_when_its_stdin_closes(tmp_path: Path) -> None:
    """``btcap agent --until-stdin-closes`` (how the simulator starts robots): the parent
    closing its end, as it does by exiting, however abruptly, stops the robot cleanly."""
    path = _config(tmp_path, "cheap", impl=None, seeds=[])
    with anyio.fail_after(30):
        proc = await AsyncAgentProcess.spawn_config(path, "cheap", log_level="error")
        try:
            assert await proc.wait_ready() == {"cheap": f"ipc://{tmp_path}/cheap.sock"}
            assert proc.alive()
            assert proc.process.stdin is not None
            await proc.process.stdin.aclose()
            assert await proc.wait() == 0
        finally:
            await proc.kill()


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["int", "term"])
async def test_a_signal_stops_the_agent_with_one_line_and_128_plus_its_number(
    tmp_path: Path, sig: signal.Signals
) -> None:
    path = _config(tmp_path, "solo", impl=None, seeds=[])
    with anyio.fail_after(30):
        async with running_agent(path, stderr=subprocess.PIPE) as proc:
            code, err = await stop(proc, sig)
    assert code == 128 + sig
    assert err == f"btcap: {sig.name}, leaving the team\n"


@pytest.mark.slow
async def test_insecure_warns_once_when_there_are_no_keys(tmp_path: Path) -> None:
    """--insecure is allowed, but not silent: one line says what it gives away."""
    path = _config(tmp_path, "open", impl=None, seeds=[])
    with anyio.fail_after(30):
        async with running_agent(path, "--insecure", stderr=subprocess.PIPE) as proc:
            code, err = await stop(proc, signal.SIGINT)
    assert code == 128 + signal.SIGINT
    lines = err.splitlines()
    assert lines[0].startswith("btcap: warning: --insecure: open speaks to anyone who can reach")
    assert sum("--insecure" in line for line in lines) == 1
