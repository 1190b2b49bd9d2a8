"""The award step's I/O, once for every strategy: ask each bidder of an
:class:`~btcap.team.core.award.AwardRound` in turn, within the award timeout, and
withdraw an award that got no answer (the robot may take it late: it must not run twice).
"""

from __future__ import annotations

from typing import Any

import msgspec

from btcap.actors import Actor, ActorError, AskTimeout, within
from btcap.team.allocation.strategy import AuctionStats
from btcap.team.capabilities.capability import ASSIGNER_PATH
from btcap.team.core.award import AwardRound
from btcap.team.core.fence import speedup_of
from btcap.team.core.task import Assigned
from btcap.team.messages import AwardReply
from btcap.transports import Address

__all__ = ["offer"]


async def offer(
    actor: Actor,
    award: AwardRound,
    timeout_s: float,
    stats: AuctionStats,
    log: Any,
    *,
    event: str,
    min_wall: float = 0.0,
) -> Assigned | None:
    """The first bidder of ``award`` that accepts, or None: each declined or did not
    answer within ``timeout_s`` clock seconds (why: ``award.reasons``). Counts awards and
    declines in ``stats``; logs ``{event}.award_lost`` and ``{event}.award_declined``
    with ``log``. ``min_wall``: the least wall time to wait on a fast real clock."""
    system = actor.system
    clock = system.clock
    # On a real clock the ask's own limit (one loop timer for all of a system's asks)
    # bounds the wait, not a timeout context of its own; on a virtual one, ``within``.
    wall = clock.to_wall(timeout_s)
    limit = max(wall, min_wall) if wall > 0 else None
    rate = speedup_of(clock)
    while (ask := award.next()) is not None:
        if rate:
            ask = msgspec.structs.replace(ask, speedup=rate)
        robot = award.offered.robot
        executor = system.ref(Address(robot, ASSIGNER_PATH))
        try:
            if limit is None:
                asked = executor.ask(ask, expect=AwardReply)
                reply = await within(clock, timeout_s, asked, min_wall=min_wall)
            else:
                try:
                    reply = await executor.ask(ask, expect=AwardReply, timeout=limit)
                except AskTimeout:
                    reply = None
            if reply is None:
                raise AskTimeout(
                    f"no reply from {executor.address} to the award within {timeout_s} clock s"
                )
        except (ActorError, TypeError) as exc:
            executor.tell(award.unanswered(str(exc)), sender=actor.address)
            log.info(f"{event}.award_lost", auction=str(award.auction), robot=robot, error=str(exc))
            stats.declined_awards += 1
            continue
        except BaseException:  # cancelled: withdraw too, then give up
            executor.tell(award.withdrawal(), sender=actor.address)
            raise
        if reply.accepted:
            stats.awarded += 1
            return award.accepted(reply.stamp)
        stats.declined_awards += 1
        why = award.declined(reply.reason)
        log.info(f"{event}.award_declined", auction=str(award.auction), robot=robot, reason=why)
    return None
