"""tests/sidework.py's worker judges as the test process does: a warning that fails a
test here fails the work there, and the warnings the suite ignores stay ignored."""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator

import pytest
from sidework import SideWork

import btcap


@pytest.fixture
def side() -> Iterator[SideWork]:
    if os.environ.get("PYTEST_XDIST_WORKER"):
        pytest.skip("the side worker is off under pytest-xdist")
    work = SideWork()
    try:
        yield work
    finally:
        work.close()


@pytest.mark.slow  # spawns a process
def test_a_warning_on_the_worker_is_an_error_as_here(side: SideWork) -> None:
    side.submit("told", warnings.warn, "told on the worker", RuntimeWarning)
    side.submit("ignored", warnings.warn, "ignored on the worker", btcap.NodeErrorWarning)
    told, ignored = side.take("told"), side.take("ignored")
    assert told is not None
    assert ignored is not None
    with pytest.raises(RuntimeWarning, match="told on the worker"):
        told.result(timeout=120)  # a hang bound
    assert ignored.result(timeout=120) is None
    assert side.take("told") is None  # handed over once
