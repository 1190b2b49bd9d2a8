"""Fixtures of the simulator-behind-ROS 2 tests: real rclpy nodes on a ROS domain of the
test's own, inside the private network namespace ``make test-ros`` runs them in
(tests/rosnet.py). Elsewhere (no rclpy, no btcap_sim_msgs, not in the namespace) the tests
marked ``ros`` skip with the reason."""

from __future__ import annotations

import importlib.util
import itertools
import os
from collections.abc import Iterator

import pytest
import rosnet

# Half a cycle on from tests/btcap/ros's domains, so the two folders' tests never share one.
_DOMAINS = itertools.islice(rosnet.domain_ids(), 50, None)


def _why_not() -> str | None:
    for module in ("rclpy", "btcap_sim_msgs"):
        if importlib.util.find_spec(module) is None:
            return f"{module} is not installed here: `make test-ros` runs these in .venv-ros"
    return rosnet.private()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    why = _why_not()
    if why is None:
        return
    for item in items:
        if item.get_closest_marker("ros") is not None and "sim/ros2" in str(item.path):
            item.add_marker(pytest.mark.skip(reason=why))


@pytest.fixture
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> Iterator[int]:
    """A ROS_DOMAIN_ID of this test's own, exported (rclpy takes it from there)."""
    domain = next(_DOMAINS)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.delenv("ROS_NAMESPACE", raising=False)
    yield domain
    assert os.environ["ROS_DOMAIN_ID"] == str(domain)
