"""Configuration for the command-line tests."""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest


@pytest.fixture
def tmp_path() -> Iterator[Path]:
    """A short temporary folder instead of pytest's own: the tests here bind ZeroMQ ipc
    sockets in it, whose path may hold at most 107 bytes, and btcap derives longer names
    from them (``operator.sock-operator+status-15e289``). Under pytest-xdist pytest's
    folder (``/tmp/pytest-of-USER/pytest-N/popen-gwN/<test name>N``) left too few."""
    with tempfile.TemporaryDirectory(prefix="btcap-cli-", ignore_cleanup_errors=True) as folder:
        yield Path(folder)
