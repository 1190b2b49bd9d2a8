"""The suite's time bounds hold on a loaded machine: a ``slow`` test (whole missions, OS
processes) is not cut short by pytest-timeout's 60 s default before its own bounds."""

from __future__ import annotations

import pytest


def timeout_of(request: pytest.FixtureRequest) -> float:
    marker = request.node.get_closest_marker("timeout")
    assert marker is not None
    return float(marker.args[0])


@pytest.mark.slow
def test_a_slow_test_gets_the_suites_bound_for_slow_tests(request: pytest.FixtureRequest) -> None:
    # tests/conftest.py's SLOW_TIMEOUT_S: above the longest anyio.fail_after a slow test
    # sets for itself (300 s).
    assert timeout_of(request) >= 300


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_slow_test_keeps_a_bound_of_its_own(request: pytest.FixtureRequest) -> None:
    assert timeout_of(request) == 120
