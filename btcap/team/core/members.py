"""Who is in the team: joins, goodbyes and silent failures decided on explicit time."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

__all__ = ["Member", "MemberTable", "TeamEvent"]


class TeamEvent(enum.Enum):
    JOINED = "joined"
    LEFT = "left"
    FAILED = "failed"
    CHANGED = "changed"  # its capabilities changed (new repository version)
    FREED = "freed"  # its body came free: waiting work may go to it now


@dataclass(slots=True)
class Member:
    robot: str
    incarnation: int
    last_seen: float
    repo_version: int
    busy: bool = False
    beat: int = 0  #: its latest heartbeat number heard, directly or from a teammate
    last_direct: float = 0.0  #: when its own heartbeat last arrived


class MemberTable:
    """The failure detector of one robot, fed heartbeats and goodbyes.

    A robot is a member from its first heartbeat until its goodbye or until no heartbeat
    came for ``failure_timeout`` seconds, its own or one a teammate heard (:meth:`hearsay`).
    A robot that restarts (a new, larger incarnation) counts as failed and joined again,
    so nothing of its old life is trusted; a robot declared failed whose heartbeat arrives
    later simply joins again (its old executions were re-assigned when it failed, and
    their late reports are refused by the lease tables).
    """

    def __init__(self, robot: str, failure_timeout_s: float, *, max_members: int = 1024) -> None:
        self.robot = robot
        self.failure_timeout_s = failure_timeout_s
        self.max_members = max_members
        self.members: dict[str, Member] = {}

    def alive(self) -> frozenset[str]:
        """Every live member, this robot included."""
        return frozenset(self.members) | {self.robot}

    def heartbeat(
        self,
        robot: str,
        incarnation: int,
        repo_version: int,
        now: float,
        busy: bool = False,
        beat: int = 0,
    ) -> list[TeamEvent]:
        """What a heartbeat from ``robot`` itself changes, in order."""
        if robot == self.robot:
            return []
        events: list[TeamEvent] = []
        m = self.members.get(robot)
        if m is not None and incarnation < m.incarnation:
            return events  # a late word from before its restart (incarnations only grow)
        if m is not None and m.incarnation != incarnation:
            del self.members[robot]
            events.append(TeamEvent.FAILED)
            m = None
        if m is None:
            if len(self.members) >= self.max_members:
                return events  # full: a real member gets in once a silent one times out
            self.members[robot] = Member(robot, incarnation, now, repo_version, busy, beat, now)
            events.append(TeamEvent.JOINED)
            return events
        m.last_seen = max(m.last_seen, now)
        m.last_direct = max(m.last_direct, now)
        m.beat = max(m.beat, beat)
        if m.repo_version != repo_version:
            m.repo_version = repo_version
            events.append(TeamEvent.CHANGED)
        if m.busy != busy:
            m.busy = busy
            if not busy:
                events.append(TeamEvent.FREED)
        return events

    def hearsay(
        self,
        robot: str,
        incarnation: int,
        beat: int,
        now: float,
        age_s: float = 0.0,
        *,
        limit_s: float = math.inf,
    ) -> bool:
        """A teammate heard ``robot`` beat ``age_s`` ago: a newer beat of the life we know
        keeps it alive from then on, for at most ``limit_s`` after its own last heartbeat
        to us (a teammate that lies about a dead robot cannot keep it alive for ever).

        Hearsay never makes a member, ends one or changes what it offers: only the robot
        itself does that. True if ``robot`` is not a member yet (worth an introduction).
        """
        if robot == self.robot:
            return False
        m = self.members.get(robot)
        if m is None:
            return True
        fresh = beat > m.beat and math.isfinite(age_s)
        if m.incarnation == incarnation and fresh and now - m.last_direct <= limit_s:
            m.beat = beat
            m.last_seen = max(m.last_seen, min(now, now - age_s))
        return False

    def goodbye(self, robot: str, incarnation: int) -> bool:
        """Whether ``robot`` left (a goodbye of an older incarnation changes nothing)."""
        m = self.members.get(robot)
        if m is None or m.incarnation != incarnation:
            return False
        del self.members[robot]
        return True

    def expire(self, now: float) -> list[str]:
        """Members whose heartbeats stopped, removed and returned (declared failed)."""
        gone = [r for r, m in self.members.items() if now - m.last_seen > self.failure_timeout_s]
        for robot in gone:
            del self.members[robot]
        return gone
