"""When a monitor's batches fall: on the wall, or every so many seconds of a virtual
clock (:meth:`~btcap.monitor.monitor.Monitor.follow`).

On a :class:`~btcap.actors.ManualClock` a batch is a timer of the clock, not a sleeping
task: the clock then wakes nothing else for it and settles no event loop after it, so a
recorded ``--fast`` run wakes the loop as often as one nobody watches (issue 32's budget).
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable

from btcap.actors import ManualClock, TimeSource
from btcap.actors.clock import ClockTimer

__all__ = ["Pacer"]


class Pacer:
    """Calls ``flush`` every ``batch_s`` of wall time, or every ``every_s`` of a clock."""

    def __init__(self, flush: Callable[[], None], batch_s: float) -> None:
        self._flush = flush
        self.batch_s = batch_s
        self.following: TimeSource | None = None  #: the virtual clock followed, if any
        self.started = False
        self._task: asyncio.Task[None] | None = None
        # a timer of a ManualClock, armed first by a loop callback where a flusher task
        # would start (so it wakes in the same order among a deadline's sleepers)
        self._timer: ClockTimer | asyncio.Handle | None = None

    def pace(self, clock: TimeSource | None, every_s: float) -> None:
        """Batch on the wall (None) or every ``every_s`` of ``clock``."""
        self.started = True
        self._cancel()
        self.following = clock
        if isinstance(clock, ManualClock):
            self._timer = asyncio.get_running_loop().call_soon(self._arm, clock, every_s)
            return
        flusher = self._wall() if clock is None else self._on_clock(clock, every_s)
        self._task = asyncio.get_running_loop().create_task(flusher, name="monitor")

    def _cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        if self._task is not None:
            self._task.cancel()

    async def stop(self) -> None:
        self._cancel()
        if self._task is not None:
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    def _arm(self, clock: ManualClock, every_s: float) -> None:
        def fire() -> None:
            self._flush()
            self._arm(clock, every_s)  # after the batch, as a sleeping flusher re-arms

        self._timer = clock.call_later(every_s, fire)

    async def _wall(self) -> None:
        while True:
            await asyncio.sleep(self.batch_s)
            self._flush()

    async def _on_clock(self, clock: TimeSource, every_s: float) -> None:
        deadline = clock.now()
        while True:
            deadline += every_s
            await clock.sleep_until(deadline)
            self._flush()
