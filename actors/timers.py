"""An ask's timer, on the clock that decides: the wall for a real clock, the clock itself
for a virtual one (where wall time must decide nothing: how fast the machine runs would
change the run)."""

from __future__ import annotations

import asyncio
import math
from typing import Any

from btcap.actors.clock import ClockTimer, ManualClock, TimeSource
from btcap.actors.errors import ActorError

__all__ = ["Expired", "arm_timer", "relay_reply"]


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
