"""Fixtures for the actor runtime tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from structlog.testing import capture_logs


@pytest.fixture(autouse=True)
def plain_logs() -> Iterator[None]:
    """Capture log events instead of rendering them (many tests fail handlers on purpose).

    The events are printed as plain dicts, so pytest shows them for a failing test.
    Tests that assert on logs nest their own ``capture_logs()``.
    """
    with capture_logs() as entries:
        yield
    for entry in entries:
        print(entry)
