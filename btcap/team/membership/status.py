"""The desk that answers observers: one :class:`~btcap.team.messages.StatusQuery`, one
reply with what this robot offers, runs and sees of its team.

Observers (``btcap team status``) are never members: they send no heartbeats, so they
are never counted, bid to, awarded work or asked to vouch; this desk is all they reach.
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.actors import Actor, Supervision, handler
from btcap.team.ids import ExecutionId
from btcap.team.membership.membership import Membership
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import Seen, StatusQuery, TeamStatus

__all__ = ["StatusDesk"]


class StatusDesk(Actor):
    """Answers :class:`StatusQuery` from anyone the transport let through (with keys, any
    member or observer; the role table allows observers nothing else)."""

    PATH = "status"
    supervision = Supervision.RESUME

    def __init__(
        self,
        team: Membership,
        repository: CapabilityRepository,
        activity: Callable[[], tuple[list[ExecutionId], list[ExecutionId]]],
    ) -> None:
        super().__init__()
        self.team = team
        self.repository = repository
        self._activity = activity

    @handler
    def on_status_query(self, msg: StatusQuery) -> TeamStatus:
        now = self.system.clock.now()
        transport = self.system.transport
        seen = []
        for robot, member in sorted(self.team.members.items()):
            endpoint = transport.endpoint_of(robot) if transport is not None else None
            age_ms = max(0, round(1000 * (now - member.last_seen)))
            seen.append(Seen(robot, endpoint or "", age_ms))
        own = self.repository.state()
        running, queued = self._activity()
        return TeamStatus(self.team.robot, own.interfaces, own.succeeded, running, queued, seen)
