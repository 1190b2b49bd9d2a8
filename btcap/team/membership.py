"""Team membership: robots announce themselves by heartbeat; joins, leaves and silent
failures are detected here and reported to local listeners."""

from __future__ import annotations

import enum
import time
from collections.abc import Callable
from dataclasses import dataclass

import structlog

from btcap.actors import Actor, handler
from btcap.team.messages import Goodbye, Heartbeat

__all__ = ["Member", "Membership", "TeamEvent"]

log = structlog.get_logger("btcap.team")


class TeamEvent(enum.Enum):
    JOINED = "joined"
    LEFT = "left"
    FAILED = "failed"
    CHANGED = "changed"  # its capabilities changed (new repository version)


@dataclass(slots=True)
class Member:
    robot: str
    incarnation: int
    last_seen: float
    repo_version: int


Listener = Callable[[TeamEvent, str], None]


class Membership(Actor):
    """Heartbeats out, heartbeats in, and a failure detector on clock time.

    A robot is a member from its first heartbeat until its :class:`Goodbye` or until no
    heartbeat came for ``failure_timeout`` clock seconds. A robot that restarts (new
    incarnation) counts as failed and joined again, so its old executions are not trusted.
    """

    PATH = "team"

    def __init__(
        self,
        robot: str,
        *,
        heartbeat_s: float = 0.1,
        failure_timeout_s: float = 0.5,
        repo_version: Callable[[], int] = lambda: 0,
    ) -> None:
        super().__init__()
        if failure_timeout_s <= heartbeat_s:
            raise ValueError("failure_timeout_s must exceed heartbeat_s")
        self.robot = robot
        self.incarnation = time.time_ns()
        self.heartbeat_s = heartbeat_s
        self.failure_timeout_s = failure_timeout_s
        self._repo_version = repo_version
        self.members: dict[str, Member] = {}
        self._listeners: list[Listener] = []
        self.history: list[tuple[float, TeamEvent, str]] = []

    # -- observing --------------------------------------------------------------------
    def subscribe(self, listener: Listener) -> Callable[[], None]:
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    def alive(self) -> frozenset[str]:
        """Every live member, this robot included."""
        return frozenset(self.members) | {self.robot}

    def _emit(self, event: TeamEvent, robot: str) -> None:
        self.history.append((self.system.clock.now(), event, robot))
        log.info("team.event", robot=self.robot, change=event.value, member=robot)
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
            self.PATH, Heartbeat(self.robot, self.incarnation, self._repo_version())
        )

    async def _beat(self) -> None:
        clock = self.system.clock
        while True:
            self.beat_now()
            self.check(clock.now())
            await clock.sleep(self.heartbeat_s)

    def check(self, now: float) -> None:
        """Declare members failed whose heartbeats stopped."""
        for robot, m in list(self.members.items()):
            if now - m.last_seen > self.failure_timeout_s:
                del self.members[robot]
                self._emit(TeamEvent.FAILED, robot)

    # -- messages ---------------------------------------------------------------------
    @handler
    def on_heartbeat(self, msg: Heartbeat) -> None:
        if msg.robot == self.robot:
            return
        now = self.system.clock.now()
        m = self.members.get(msg.robot)
        if m is not None and m.incarnation != msg.incarnation:
            del self.members[msg.robot]
            self._emit(TeamEvent.FAILED, msg.robot)
            m = None
        if m is None:
            self.members[msg.robot] = Member(msg.robot, msg.incarnation, now, msg.repo_version)
            self._emit(TeamEvent.JOINED, msg.robot)
            self.beat_now()  # let the newcomer know us without waiting a period
            return
        m.last_seen = now
        if m.repo_version != msg.repo_version:
            m.repo_version = msg.repo_version
            self._emit(TeamEvent.CHANGED, msg.robot)

    @handler
    def on_goodbye(self, msg: Goodbye) -> None:
        m = self.members.get(msg.robot)
        if m is not None and m.incarnation == msg.incarnation:
            del self.members[msg.robot]
            self._emit(TeamEvent.LEFT, msg.robot)
