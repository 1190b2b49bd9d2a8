"""Fixtures of the ROS 2 tests: real rclpy nodes, each test on a ROS domain of its own,
inside the private network namespace ``make test-ros`` runs them in (tests/rosnet.py).

Tests marked ``ros`` need rclpy (installed in .venv-ros, not .venv) and that namespace;
elsewhere they skip with the reason, so `make test` in .venv skips them and `make
test-ros` runs them.
"""

from __future__ import annotations

import importlib.util
import os
import warnings
from collections.abc import AsyncIterator, Callable, Iterator

import pytest
import rosnet
from rosservers import Servers

from btcap.ros.client import RosBridge
from btcap.ros.errors import RosTypeWarning
from btcap.team.rossettings import RosSettings

_DOMAINS = rosnet.domain_ids()


def _why_not() -> str | None:
    if importlib.util.find_spec("rclpy") is None:
        return "ROS 2 (rclpy) is not installed here: `make test-ros` runs these in .venv-ros"
    return rosnet.private()


#: What rmw says (as a RuntimeWarning, from a server's executor thread) when a client left
#: before its response could be delivered: the tests close clients with requests open.
_LEFT = "ignore:failed to send response:RuntimeWarning"


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    why = _why_not()
    for item in items:
        if item.get_closest_marker("ros") is not None:
            item.add_marker(pytest.mark.filterwarnings(_LEFT))
    if why is None:
        return
    for item in items:
        if item.get_closest_marker("ros") is not None:
            item.add_marker(pytest.mark.skip(reason=why))


@pytest.fixture
def servers(ros_domain: int) -> Iterator[Servers]:
    """The test servers (rosservers.py) in namespace /husky1."""
    with Servers("/husky1", domain_id=ros_domain) as s:
        yield s


@pytest.fixture
async def bridge(ros_domain: int) -> AsyncIterator[RosBridge]:
    """Robot husky1's bridge (namespace /husky1), closed after the test."""
    async with RosBridge(RosSettings(domain_id=ros_domain), robot="husky1") as b:
        yield b
    assert b.node is None


@pytest.fixture
def told() -> Iterator[Callable[[], list[str]]]:
    """The RosTypeWarnings said so far (from the bridge's executor thread too)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RosTypeWarning)
        yield lambda: [str(w.message) for w in caught if w.category is RosTypeWarning]


@pytest.fixture
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> Iterator[int]:
    """A ROS_DOMAIN_ID no other test of this run uses at the same time; exported, so
    server processes a test starts join it."""
    domain = next(_DOMAINS)
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.delenv("ROS_NAMESPACE", raising=False)
    yield domain
    assert os.environ["ROS_DOMAIN_ID"] == str(domain)
