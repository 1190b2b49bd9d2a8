"""Explicit time: every protocol and simulation duration goes through a clock.

A :class:`Clock` runs ``speedup`` times faster than the wall, so a 20-minute simulated
mission can take seconds; a :class:`ManualClock` only moves when told, for tests.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import time
from typing import Protocol, runtime_checkable

__all__ = ["Clock", "ManualClock", "TimeSource"]


@runtime_checkable
class TimeSource(Protocol):
    """What time-aware code needs: now, and a sleep measured in clock seconds."""

    @property
    def speedup(self) -> float: ...

    def now(self) -> float: ...

    async def sleep(self, seconds: float) -> None: ...

    async def sleep_until(self, deadline: float) -> None: ...

    def to_wall(self, seconds: float) -> float: ...


class Clock:
    """Clock seconds since creation, running ``speedup`` times faster than the wall."""

    __slots__ = ("_origin", "speedup")

    def __init__(self, speedup: float = 1.0) -> None:
        if not speedup > 0:
            raise ValueError(f"speedup must be > 0, got {speedup!r}")
        self.speedup = float(speedup)
        self._origin = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._origin) * self.speedup

    def to_wall(self, seconds: float) -> float:
        return seconds / self.speedup

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds) / self.speedup)

    async def sleep_until(self, deadline: float) -> None:
        await self.sleep(deadline - self.now())


class ManualClock:
    """A clock that advances only through :meth:`advance`, waking sleepers in order."""

    def __init__(self, start: float = 0.0) -> None:
        self._now = float(start)
        self._sleepers: list[tuple[float, int, asyncio.Future[None]]] = []
        self._seq = itertools.count()

    @property
    def speedup(self) -> float:
        return float("inf")

    def now(self) -> float:
        return self._now

    def to_wall(self, seconds: float) -> float:
        return 0.0

    async def sleep(self, seconds: float) -> None:
        await self.sleep_until(self._now + max(0.0, seconds))

    async def sleep_until(self, deadline: float) -> None:
        if deadline <= self._now:
            await asyncio.sleep(0)
            return
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (deadline, next(self._seq), fut))
        await fut

    async def advance(self, seconds: float) -> None:
        """Move time forward, letting each woken sleeper run before time moves on."""
        target = self._now + seconds
        while self._sleepers and self._sleepers[0][0] <= target:
            deadline, _, fut = heapq.heappop(self._sleepers)
            self._now = max(self._now, deadline)
            if not fut.done():
                fut.set_result(None)
            for _ in range(3):
                await asyncio.sleep(0)
        self._now = target
        await asyncio.sleep(0)

    @property
    def pending(self) -> int:
        return sum(1 for _, _, f in self._sleepers if not f.done())
