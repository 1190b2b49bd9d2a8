"""Without ROS: an agent whose file has no ``ros:`` block imports nothing of the bridge or
of ROS; one whose file has it, where ROS is not installed, says how to install it in one
line and exits. These run in .venv (no ROS), not in `make test-ros`."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

AGENT = """\
btcap: 1
robot: husky1
"""


def test_an_agent_without_a_ros_block_imports_nothing_of_ros(tmp_path: Path) -> None:
    (tmp_path / "agent.yaml").write_text(AGENT)
    script = textwrap.dedent(
        f"""
        import json, sys, anyio
        from btcap.bt.registry import default_registry
        from btcap.team.deployment.agentconfig import load_agent_file
        from btcap.team.deployment.deploy import open_agent

        async def main():
            config = load_agent_file({str(tmp_path / "agent.yaml")!r})
            async with open_agent(config, default_registry()) as agent:
                assert agent.robot == "husky1"

        anyio.run(main)
        print(json.dumps(sorted(sys.modules)))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    modules = json.loads(done.stdout.splitlines()[-1])
    assert "btcap.team.deployment.deploy" in modules
    ros = [m for m in modules if m.startswith(("btcap.ros", "rclpy", "rcl_", "rosidl"))]
    assert ros == []


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None, reason="ROS 2 is installed here")
def test_a_ros_block_without_ros_installed_says_how_to_install_it(tmp_path: Path) -> None:
    (tmp_path / "agent.yaml").write_text(AGENT + "ros: {domain_id: 7}\n")
    done = subprocess.run(
        [sys.executable, "-m", "btcap", "agent", str(tmp_path / "agent.yaml")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"btcap: error: {tmp_path / 'agent.yaml'}: ros: ROS 2 (rclpy")
    assert "is not installed: install it with `make ros`" in lines[0]
