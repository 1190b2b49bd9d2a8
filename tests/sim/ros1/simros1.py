"""Helpers of the simulator-behind-ROS 1 tests (not a conftest: tests/btcap/ros1 imports
its own ``conftest`` by that name): why they cannot run here, every ROS 1 process on
loopback (``ROS_IP``) with no master or namespace of the environment's, and the child
processes left behind. Elsewhere (no rospy, no btcap_sim1_msgs, no rosmaster) the tests
skip with the reason: `make test-ros1` runs them in .venv-ros1."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from btcap.sim.ros1 import ros1_missing


def why_not() -> str | None:
    if (why := ros1_missing()) is not None:
        return why
    if shutil.which("rosmaster", path=f"{os.environ.get('PATH', '')}:/usr/bin") is None:
        return "ROS 1's rosmaster is not installed (Debian's python3-rosmaster): `make ros1`"
    return None


#: Why the ROS 1 simulator tests cannot run here, or None.
WHY_NOT = why_not()


@pytest.fixture
def loopback(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """ROS 1 processes of this test bind to 127.0.0.1 and log under ``tmp_path``."""
    for name in ("ROS_MASTER_URI", "ROS_NAMESPACE", "ROS_HOSTNAME"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("ROS_IP", "127.0.0.1")
    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    monkeypatch.setenv("ROS_LOG_DIR", str(tmp_path / "log"))


def children() -> list[str]:
    """The command lines of this process's child processes still alive (or unreaped)."""
    me, found = os.getpid(), []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
            cmd = (stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if int(text.rsplit(")", 1)[1].split()[1]) == me:
            found.append(cmd.strip())
    return found
