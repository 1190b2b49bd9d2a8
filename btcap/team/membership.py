"""Team membership: robots announce themselves by heartbeat; joins, leaves and silent
failures are detected here and reported to local listeners."""

from __future__ import annotations

import time
from collections.abc import Callable

from btcap.actors import Actor, Supervision, handler
from btcap.team.core.members import Member, MemberTable, TeamEvent
from btcap.team.messages import Goodbye, Heartbeat
from btcap.transports.log import get_logger, worth_logging

__all__ = ["Member", "Membership", "TeamEvent"]

log = get_logger("btcap.team")


Listener = Callable[[TeamEvent, str], None]


class Membership(Actor):
    """Heartbeats out, heartbeats in, and a failure detector on clock time.

    The decisions are :class:`~btcap.team.core.members.MemberTable`'s; this actor sends
    the heartbeats and tells local listeners what changed.
    """

    PATH = "team"
    #: Input from peers must never stop it (a bug shows as a logged failure, not silence).
    supervision = Supervision.RESUME

    def __init__(
        self,
        robot: str,
        *,
        heartbeat_s: float = 0.1,
        failure_timeout_s: float = 0.5,
        repo_version: Callable[[], int] = lambda: 0,
        busy: Callable[[], bool] = lambda: False,
    ) -> None:
        super().__init__()
        if failure_timeout_s <= heartbeat_s:
            raise ValueError("failure_timeout_s must exceed heartbeat_s")
        self.robot = robot
        self.incarnation = time.time_ns()
        self.heartbeat_s = heartbeat_s
        self.failure_timeout_s = failure_timeout_s
        self._repo_version = repo_version
        self._body_busy = busy
        self.table = MemberTable(robot, failure_timeout_s)
        self.refused = 0  #: heartbeats and goodbyes sent in another robot's name
        self._listeners: list[Listener] = []

    # -- observing --------------------------------------------------------------------
    def subscribe(self, listener: Listener) -> Callable[[], None]:
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    @property
    def members(self) -> dict[str, Member]:
        return self.table.members

    def alive(self) -> frozenset[str]:
        """Every live member, this robot included."""
        return self.table.alive()

    def _emit(self, event: TeamEvent, robot: str) -> None:
        emit = log.debug if event is TeamEvent.FREED else log.info  # routine, not a change
        emit("team.event", robot=self.robot, change=event.value, member=robot)
        for listener in list(self._listeners):
            try:
                listener(event, robot)
            except Exception as exc:
                log.error("team.listener_failed", robot=self.robot, exc_info=exc)

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self.start_task(self._beat(), name=f"heartbeat {self.robot}")

    def on_stop(self) -> None:
        system = self._system
        if system is not None and system.transport is not None:
            system.broadcast(self.PATH, Goodbye(self.robot, self.incarnation))

    def beat_now(self) -> None:
        """Send a heartbeat at once (after a capability change, or to speed up joins)."""
        self.system.broadcast(
            self.PATH,
            Heartbeat(self.robot, self.incarnation, self._repo_version(), self._body_busy()),
        )

    async def _beat(self) -> None:
        clock = self.system.clock
        while True:
            self.beat_now()
            self.check(clock.now())
            await clock.sleep(self.heartbeat_s)

    def check(self, now: float) -> None:
        """Declare members failed whose heartbeats stopped."""
        for robot in self.table.expire(now):
            self._emit(TeamEvent.FAILED, robot)

    # -- messages ---------------------------------------------------------------------
    def _speaks_for_itself(self, robot: str, msg: Heartbeat | Goodbye) -> bool:
        """A robot speaks only for itself: the transport authenticated the sender."""
        if robot == self.sender:
            return True
        self.refused += 1
        if worth_logging(self.refused):
            log.warning(
                "team.refused",
                robot=self.robot,
                sender=self.sender,
                message=type(msg).__name__,
                claims=robot[:64],
                count=self.refused,
            )
        return False

    @handler
    def on_heartbeat(self, msg: Heartbeat) -> None:
        if not self._speaks_for_itself(msg.robot, msg):
            return
        now = self.system.clock.now()
        events = self.table.heartbeat(msg.robot, msg.incarnation, msg.repo_version, now, msg.busy)
        for event in events:
            self._emit(event, msg.robot)
        if TeamEvent.JOINED in events:
            self.beat_now()  # let the newcomer know us without waiting a period

    @handler
    def on_goodbye(self, msg: Goodbye) -> None:
        if self._speaks_for_itself(msg.robot, msg) and self.table.goodbye(
            msg.robot, msg.incarnation
        ):
            self._emit(TeamEvent.LEFT, msg.robot)
