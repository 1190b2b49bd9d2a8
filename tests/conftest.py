"""Shared test configuration for the whole suite."""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import structlog
from hypothesis import HealthCheck, settings

# pytest puts this folder on sys.path to import this file; its ``actors/`` and
# ``transports/`` test folders would then shadow the real packages (as namespace
# packages, ahead of the editable install's finder). Put the project root first, as
# ``python -m pytest`` does.
_ROOT = str(Path(__file__).resolve().parent.parent)
if _ROOT not in sys.path:
    sys.path.insert(0, _ROOT)

# No per-example deadline: a loaded CI machine must not turn a slow first example into a
# failure. Example counts stay small and explicit in each test.
settings.register_profile(
    "btcap",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    print_blob=True,
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "btcap"))

# btcap's debug mode for every Tree the suite makes (and the processes it starts): a node
# caught in a restart loop raises a RestartLoopWarning, which filterwarnings=error turns
# into a failure; a test that makes one on purpose expects it (pytest.warns).
os.environ["BTCAP_DEBUG"] = "1"


@pytest.fixture(autouse=True)
def _restore_logging() -> Iterator[None]:
    """A test that runs the CLI configures logging for the process (on a stderr pytest
    closes afterwards): put the root logger and structlog back as they were."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    config = structlog.get_config()
    yield
    root.handlers[:] = handlers
    root.setLevel(level)
    structlog.configure(**config)


#: pytest-timeout's bound for a test marked ``slow`` that sets none of its own: such a
#: test runs whole missions or OS processes, and bounds its waits itself with
#: ``anyio.fail_after`` (up to 300 s). The default 60 s (pyproject) would cut it short on
#: a machine loaded 5-15 deep on 2 cores (CI's are that busy) although nothing hangs.
#: The bound catches hangs; it does not measure speed.
SLOW_TIMEOUT_S = 900.0


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Give ``slow`` tests without a ``timeout`` marker :data:`SLOW_TIMEOUT_S`."""
    for item in items:
        if item.get_closest_marker("slow") and item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(SLOW_TIMEOUT_S))


def _modules(items: list[pytest.Item]) -> dict[object, list[pytest.Item]]:
    mine: dict[object, list[pytest.Item]] = {}
    for item in items:
        module = getattr(item, "module", None)
        if module is not None:
            mine.setdefault(module, []).append(item)
    return mine


def pytest_collection_finish(session: pytest.Session) -> None:
    """A test module may start deterministic work its tests will read (``start_ahead``,
    given its selected tests) once the suite is collected, to run beside the tests
    before it; ``stop_ahead`` ends it after its last test, or with the session."""
    if session.config.option.collectonly:
        return
    for module, items in _modules(session.items).items():
        start = getattr(module, "start_ahead", None)
        if callable(start):
            start(items)


def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    """A module's work ahead ends with its last test (``stop_ahead``), so no later test
    sees its worker (tests/sim/running/test_sweep.py counts leftover processes)."""
    module = getattr(item, "module", None)
    if module is not None and getattr(nextitem, "module", None) is not module:
        stop = getattr(module, "stop_ahead", None)
        if callable(stop):
            stop()


def pytest_sessionfinish(session: pytest.Session) -> None:
    for module in _modules(session.items):
        stop = getattr(module, "stop_ahead", None)
        if callable(stop):
            stop()
