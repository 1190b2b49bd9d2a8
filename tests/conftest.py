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
