"""Fixtures of the ROS 1 tests: a real ``rosmaster`` of the test's own, on a free loopback
port, started and stopped around each test that asks for it.

Tests marked ``ros1`` need Debian's rospy (``make ros1`` installs it and .venv-ros1 sees
it); elsewhere they skip with the reason, so `make test` in .venv skips them and `make
test-ros1` runs them.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterator
from pathlib import Path

import pytest
from rosmaster1 import Master


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
def master(tmp_path: Path) -> Iterator[Master]:
    """A rosmaster of this test's own on 127.0.0.1 (its logs under ``tmp_path``), stopped
    and reaped after the test."""
    with Master(tmp_path) as m:
        yield m
    assert m.process is not None
    assert m.process.returncode is not None
