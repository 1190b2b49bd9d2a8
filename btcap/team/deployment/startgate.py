"""How many robots' processes start at once: starting one is CPU work (an interpreter,
its imports, its capability files), so starting many at once on a small machine makes
every one of them late, and a ready deadline counted from the batch's start fails robots
that were merely waiting for a core. Starters hold a turn of a :class:`StartGate` from
before a process is created until its agents listen, and count its deadline from there.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

import anyio

__all__ = ["STARTS_AT_ONCE", "StartGate", "check_at_once"]

#: Agent processes started at once by default: a few keep both cores of a small machine
#: busy; 50 at once made each late enough to miss a 20 s ready deadline under load.
STARTS_AT_ONCE = 4


def check_at_once(at_once: int) -> None:
    if at_once < 1:
        raise ValueError(f"at_once={at_once}: expected at least 1 process starting at a time")


class StartGate:
    """At most ``at_once`` agent processes starting at a time: hold a :meth:`turn` from
    before a process is created until its agents listen (or it failed to start).
    ``starting`` counts the turns held now, ``peak`` the most held at once."""

    def __init__(self, at_once: int = STARTS_AT_ONCE) -> None:
        check_at_once(at_once)
        self.at_once = at_once
        self._limiter = anyio.CapacityLimiter(at_once)
        self.starting = 0
        self.peak = 0

    @asynccontextmanager
    async def turn(self) -> AsyncIterator[None]:
        """Wait for a turn, and hold it while the block runs."""
        async with self._limiter:
            self.starting += 1
            self.peak = max(self.peak, self.starting)
            try:
                yield
            finally:
                self.starting -= 1
