"""Fixtures of the ROS 1 tests: a real ``rosmaster`` of the test's own, on a free loopback
port, started and stopped around each test that asks for it.

Tests marked ``ros1`` need Debian's rospy (``make ros1`` installs it and .venv-ros1 sees
it); elsewhere they skip with the reason, so `make test` in .venv skips them and `make
test-ros1` runs them.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import threading
import warnings
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from rosmaster1 import READY_S, Master

from btcap.ros.errors import RosTypeWarning


def _why_not() -> str | None:
    if importlib.util.find_spec("rospy") is None:
        return "ROS 1 (Debian's rospy) is not importable here: `make test-ros1` runs these"
    if Master.executable() is None:
        return "ROS 1's rosmaster is not installed (Debian's python3-rosmaster): `make ros1`"
    return None


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    why = _why_not()
    if why is None:
        return
    for item in items:
        if item.get_closest_marker("ros1") is not None:
            item.add_marker(pytest.mark.skip(reason=why))


@pytest.fixture
def told() -> Iterator[Callable[[], list[str]]]:
    """The RosTypeWarnings said so far (from the bridge's threads too)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RosTypeWarning)
        yield lambda: [str(w.message) for w in caught if w.category is RosTypeWarning]


@pytest.fixture
def master(tmp_path: Path) -> Iterator[Master]:
    """A rosmaster of this test's own on 127.0.0.1 (its logs under ``tmp_path``), stopped
    and reaped after the test."""
    with Master(tmp_path) as m:
        yield m
    assert m.process is not None
    assert m.process.returncode is not None


class Servers:
    """tests/btcap/ros1/servers1.py running on a master, in namespace ``/husky1``: its
    events (stdout lines) counted as they come."""

    def __init__(self, master: Master, namespace: str = "/husky1") -> None:
        env = dict(master.env(), ROS_NAMESPACE=namespace)
        self.process = subprocess.Popen(
            [sys.executable, str(Path(__file__).with_name("servers1.py"))],
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.events: Counter[str] = Counter()
        self.lines: list[str] = []
        self._up = threading.Event()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        if not self._up.wait(READY_S):
            self.stop()
            raise RuntimeError(f"servers1.py: not up within {READY_S} s")

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            text = line.strip()
            self.lines.append(text)
            self.events[text.split(" ")[0]] += 1
            if text == "up":
                self._up.set()

    def kill(self) -> None:
        """Kill the servers (no goodbye to the master), reaped."""
        self.process.kill()
        self.process.wait()

    def stop(self) -> None:
        process = self.process
        assert process.stdin is not None
        process.stdin.close()
        if process.returncode is None:
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self._reader.join(timeout=5)
        if process.stdout is not None:
            process.stdout.close()


@pytest.fixture
def servers(master: Master) -> Iterator[Servers]:
    s = Servers(master)
    try:
        yield s
    finally:
        s.stop()
