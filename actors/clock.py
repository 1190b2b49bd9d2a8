"""Explicit time: every protocol and simulation duration goes through a clock.

A :class:`Clock` runs ``speedup`` times faster than the wall, so a 20-minute simulated
mission can take seconds; a :class:`ManualClock` only moves when told, for tests.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import itertools
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import Any, Protocol, TypeVar, runtime_checkable

__all__ = ["Clock", "ClockTimer", "ManualClock", "TimeSource", "within"]

T = TypeVar("T")


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
    """A clock that advances only through :meth:`advance`, waking sleepers in order.

    Between two wake-ups :meth:`advance` lets the event loop run until nothing is ready
    to run, however many hand-offs the woken work makes, so a test sees the effects of
    each deadline before time moves on. Work that waits on real I/O or on another
    thread is not waited for: that is not something virtual time can settle.
    """

    def __init__(self, start: float = 0.0) -> None:
        self._now = float(start)
        self._sleepers: list[tuple[float, int, asyncio.Future[None] | ClockTimer]] = []
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

    def call_later(self, seconds: float, callback: Callable[..., object], *args: Any) -> ClockTimer:
        """Call ``callback(*args)`` once the clock reaches ``now + seconds`` (a timer on
        this clock, as ``loop.call_later`` is one on the wall), in deadline order with the
        sleepers; ``cancel()`` the returned timer to disarm it."""
        timer = ClockTimer(callback, args)
        heapq.heappush(self._sleepers, (self._now + max(0.0, seconds), next(self._seq), timer))
        return timer

    async def advance(self, seconds: float) -> None:
        """Move time forward by ``seconds``, waking each sleeper at its own deadline.

        Runs what is ready before time moves, and after each wake-up lets the woken
        work settle before the next deadline, so a sleeper that sleeps again within the
        interval wakes again in this call.
        """
        if not seconds >= 0:
            raise ValueError(f"advance by {seconds!r}: expected seconds >= 0")
        target = self._now + seconds
        await _settle()
        ready = getattr(asyncio.get_running_loop(), "_ready", None)  # _settle checked it
        while self._sleepers and self._sleepers[0][0] <= target:
            deadline, _, fut = heapq.heappop(self._sleepers)
            if fut.done():  # its sleeper was cancelled
                continue
            self._now = max(self._now, deadline)
            fut.set_result(None)
            if not ready and fut.__class__ is ClockTimer:
                continue  # a timer that made nothing ready (a monitor's batch): no settling
            await _settle()
        self._now = target
        await _settle()

    @property
    def pending(self) -> int:
        return sum(1 for _, _, f in self._sleepers if not f.done())

    def next_deadline(self) -> float | None:
        """When the earliest sleeper wakes, or None if nobody sleeps."""
        heap = self._sleepers
        while heap and heap[0][2].done():  # cancelled sleepers
            heapq.heappop(heap)
        return heap[0][0] if heap else None

    @contextlib.asynccontextmanager
    async def autojump(self, *, idle_wait: float = 0.001) -> AsyncIterator[ManualClock]:
        """Inside the block, time jumps to the next deadline whenever nothing is ready to
        run (trio's autojump idea): code that only waits on this clock runs as fast as it
        computes, and the same inputs give the same run. When nobody sleeps on the clock
        but something waits on real I/O, real time passes ``idle_wait`` at a time."""
        driver = asyncio.get_running_loop().create_task(self._jump(idle_wait), name="autojump")
        try:
            yield self
        finally:
            driver.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await driver

    async def _jump(self, idle_wait: float) -> None:
        while True:
            await _settle()
            deadline = self.next_deadline()
            if deadline is None:
                await asyncio.sleep(idle_wait)
            else:
                await self.advance(max(0.0, deadline - self._now))


class ClockTimer:
    """A :meth:`ManualClock.call_later` timer: no future and no task, since every ask
    of a virtual-time run arms one and nearly all are cancelled."""

    __slots__ = ("_args", "_callback", "_done")

    def __init__(self, callback: Callable[..., object], args: tuple[Any, ...]) -> None:
        self._callback = callback
        self._args = args
        self._done = False

    def cancel(self) -> None:
        self._done = True

    def done(self) -> bool:
        return self._done

    def set_result(self, _: None) -> None:
        """Fire (the clock treats it as a sleeper's future)."""
        self._done = True
        self._callback(*self._args)


async def within(
    clock: TimeSource, seconds: float, aw: Awaitable[T], *, min_wall: float = 0.0
) -> T | None:
    """``aw``'s result, or None once ``seconds`` of clock time have passed (``aw`` is then
    cancelled); an error of ``aw`` propagates, and so does our own cancellation (which
    cancels ``aw`` too).

    On a real clock one wall-time limit (at least ``min_wall``) bounds the wait. On a
    virtual one the clock decides: ``aw`` races a sleep on it, ``aw`` started first (the
    order virtual-time runs are reproducible by).
    """
    wall = clock.to_wall(seconds)
    if wall > 0:
        limit = asyncio.timeout(max(wall, min_wall))
        try:
            async with limit:
                return await aw
        except TimeoutError:
            if limit.expired():
                return None
            raise  # ``aw``'s own timeout error
    job = asyncio.ensure_future(aw)
    timer = asyncio.ensure_future(clock.sleep(seconds))
    try:
        await asyncio.wait((job, timer), return_when=asyncio.FIRST_COMPLETED)
    finally:
        timer.cancel()
        if not job.done():  # timed out, or we were cancelled: the job goes too
            job.cancel()
    return job.result() if job.done() and not job.cancelled() else None


_SETTLE_ROUNDS = 100_000
"""Loop iterations :func:`_settle` allows before it calls the work a busy loop."""


async def _settle() -> None:
    """Return once the running event loop has nothing ready to run but this task.

    Yields one loop iteration at a time until no callback is ready. Event loop timers
    (wall time) are not work to wait for: whether one is due when the loop settles
    depends on how fast the machine runs, so counting them would let the machine's load
    decide what happens before virtual time moves on (and scanning the timer heap on
    every iteration made large runs quadratic). asyncio offers no public way to ask
    whether a callback is ready, so this reads the stdlib loop's ready queue
    (``BaseEventLoop._ready``, stable since Python 3.4; aiotools' VirtualClock and
    looptime reach into the same loop internals). A loop without it, such as uvloop's,
    is refused with a clear error rather than guessed at with a fixed number of yields.
    """
    loop = asyncio.get_running_loop()
    ready = getattr(loop, "_ready", None)
    if ready is None:
        raise TypeError(
            f"ManualClock needs the standard asyncio event loop, not {type(loop).__name__}: "
            "it waits until the loop has nothing ready to run"
        )
    for _ in range(_SETTLE_ROUNDS):
        await asyncio.sleep(0)
        if not ready:
            return
    raise RuntimeError(
        f"the event loop never settled within {_SETTLE_ROUNDS} iterations: some task "
        "keeps yielding without waiting on anything (a busy loop?)"
    )
