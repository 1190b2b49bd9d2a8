"""An ask's timer, on the clock that decides: the wall for a real clock, the clock itself
for a virtual one (where wall time must decide nothing: how fast the machine runs would
change the run)."""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any

from btcap.actors.cell import Reply
from btcap.actors.clock import ClockTimer, ManualClock, TimeSource
from btcap.actors.errors import ActorError, AskTimeout

__all__ = [
    "AskDeadlines",
    "Expired",
    "arm_timer",
    "future_reply",
    "on_the_wall",
    "relay_reply",
    "timed_out",
]


class Expired(ActorError):
    """Set on an ask's future when its timer fires (the ask raises AskTimeout instead)."""


def arm_timer(
    clock: TimeSource, limit: float, fut: asyncio.Future[Any]
) -> asyncio.Handle | ClockTimer | asyncio.Future[Any]:
    """Fail ``fut`` with :class:`Expired` after ``limit`` seconds: of the wall on a real
    clock (a network round trip's time), of the clock on a virtual one. Cancel the
    returned handle to disarm it."""
    if isinstance(clock, ManualClock):
        return clock.call_later(limit, _expire, fut)
    if math.isinf(clock.speedup):  # another virtual clock: a sleep on it
        return asyncio.ensure_future(_expire_after(clock, limit, fut))
    return asyncio.get_running_loop().call_later(limit, _expire, fut)


def on_the_wall(clock: TimeSource) -> bool:
    """Whether an ask's limit on ``clock`` is wall time (see :func:`arm_timer`)."""
    return not isinstance(clock, ManualClock) and not math.isinf(clock.speedup)


class AskDeadlines:
    """Wall-clock limits of a system's remote asks on one loop timer, not one per ask.

    A timer per ask cost a TimerHandle, a heap push and a cancel on every round trip
    (~2 us, the hottest path there is). Here an ask only stores its deadline next to its
    future in ``pending`` (corr -> (peer, future, deadline)); one timer is armed at the
    soonest deadline it knows of (an ask with a later one costs a comparison), and when
    it fires it fails what has expired with :class:`Expired` and re-arms at the soonest
    left. Expiry stays exact: no ask is failed before its limit.
    """

    __slots__ = ("_pending", "_timer", "at")

    def __init__(self, pending: dict[int, tuple[str, asyncio.Future[Any], float]]) -> None:
        self._pending = pending
        self._timer: asyncio.TimerHandle | None = None
        self.at = math.inf  #: when the timer fires (inf: not armed)

    def arm(self, deadline: float) -> None:
        """Make sure the timer fires no later than ``deadline`` (``time.monotonic``)."""
        if self.at <= deadline:
            return
        if self._timer is not None:
            self._timer.cancel()
        self.at = deadline
        self._timer = asyncio.get_running_loop().call_at(deadline, self._fire)

    def cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self._timer, self.at = None, math.inf

    def _fire(self) -> None:
        self._timer, self.at = None, math.inf
        now = time.monotonic()
        soonest = math.inf
        for _peer, fut, deadline in list(self._pending.values()):
            if fut.done():
                continue  # its ask pops it
            if deadline <= now:
                fut.set_exception(Expired())  # its ask pops it and raises AskTimeout
            elif deadline < soonest:
                soonest = deadline
        if soonest < math.inf:
            # A loop whose clock is not time.monotonic (uvloop's is cached per
            # iteration) may fire a little early: then this re-arms and fires again.
            self.arm(soonest)


def relay_reply(waiter: asyncio.Future[Any], fut: asyncio.Future[Any]) -> None:
    """Hand a deferred reply on to the ask's own waiter (unless that timed out)."""
    if waiter.done():
        return
    if fut.cancelled():
        waiter.cancel()
    elif (exc := fut.exception()) is not None:
        waiter.set_exception(exc)
    else:
        waiter.set_result(fut.result())


def _expire(fut: asyncio.Future[Any]) -> None:
    if not fut.done():
        fut.set_exception(Expired())


async def _expire_after(clock: TimeSource, seconds: float, fut: asyncio.Future[Any]) -> None:
    await clock.sleep(seconds)
    _expire(fut)


def future_reply(fut: asyncio.Future[Any]) -> Reply:
    """The reply callback of a local ask: settles ``fut`` (unless it timed out)."""

    def reply(result: Any, error: BaseException | None) -> None:
        if fut.done():
            return
        if error is None:
            fut.set_result(result)
        else:
            fut.set_exception(error)

    return reply


def timed_out(address: object, msg: Any, limit: float) -> AskTimeout:
    """The error an ask raises when no reply came within ``limit`` seconds."""
    return AskTimeout(f"no reply from {address} to {type(msg).__qualname__} within {limit} s")
