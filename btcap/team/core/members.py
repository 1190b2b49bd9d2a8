"""Who is in the team: joins, goodbyes, suspicions and failures decided on explicit time.

A robot is a member from its own first heartbeat (``sender == robot``, authenticated by
the transport) until its goodbye, or until a suspicion of it ran out unrefuted
(:meth:`MemberTable.expire`; who suspects and for how long is
:mod:`btcap.team.core.swim`'s business). What teammates pass on (:meth:`MemberTable.suspect`,
:meth:`MemberTable.hearsay`) never makes a member, ends one or changes what it offers.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = ["Hearsay", "Member", "MemberTable", "Suspicion", "TeamEvent"]

#: Suspectors remembered per suspicion (more confirmations shorten nothing further).
MAX_SUSPECTORS = 8


class TeamEvent(enum.Enum):
    JOINED = "joined"
    LEFT = "left"
    FAILED = "failed"
    CHANGED = "changed"  # its capabilities changed (new repository version)
    FREED = "freed"  # its body came free: waiting work may go to it now
    #: a suspicion of it started (it may still refute it): auctions stop waiting for its
    #: answer, though it may still bid
    SUSPECTED = "suspected"


class Hearsay(enum.Enum):
    """What a teammate's news of a robot did to our table."""

    NOTHING = "nothing"  #: old news, another life, or past the hearsay window
    NEWS = "news"  #: a newer beat of a member: worth passing on
    UNKNOWN = "unknown"  #: not a member (worth an introduction, never a join)


@dataclass(slots=True)
class Suspicion:
    """Some teammates (``by``, the first first) think a member failed at ``beat``; it is
    declared failed when the suspicion outlives its timeout unrefuted."""

    beat: int
    since: float
    #: The suspectors that told us themselves (or us), first first; "" one passed on.
    by: list[str] = field(default_factory=list)
    probed_at: float = -math.inf  #: when we last probed it ourselves

    @property
    def confirmations(self) -> int:
        """Independent suspectors beyond the first (Lifeguard shortens the timeout)."""
        return max(sum(1 for b in self.by if b) - 1, 0)


@dataclass(slots=True)
class Member:
    robot: str
    incarnation: int
    last_seen: float  #: when we last heard from it directly (its own message)
    repo_version: int
    busy: bool = False
    beat: int = 0  #: the newest beat known of it, from itself or passed on
    last_direct: float = 0.0  #: same as ``last_seen`` (kept for readers of both)
    state_beat: int = 0  #: the beat of the ``busy``/``repo_version`` we hold
    suspicion: Suspicion | None = None


class MemberTable:
    """The member list of one robot, fed its teammates' own messages and their news.

    A robot that restarts (a new, larger incarnation) counts as failed and joined again,
    so nothing of its old life is trusted; a robot declared failed whose own message
    arrives later simply joins again (its old executions were re-assigned when it failed,
    and their late reports are refused by the lease tables).
    """

    def __init__(self, robot: str, *, max_members: int = 1024) -> None:
        self.robot = robot
        self.max_members = max_members
        self.members: dict[str, Member] = {}
        self.suspected: dict[str, Suspicion] = {}  #: the members under suspicion

    def alive(self) -> frozenset[str]:
        """Every live member, this robot included (suspected ones are still members)."""
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
        """What a message from ``robot`` itself changes, in order. Being heard directly
        ends any suspicion of it."""
        if robot == self.robot:
            return []
        events: list[TeamEvent] = []
        m = self.members.get(robot)
        if m is not None and incarnation < m.incarnation:
            return events  # a late word from before its restart (incarnations only grow)
        if m is not None and m.incarnation != incarnation:
            self._remove(robot)
            events.append(TeamEvent.FAILED)
            m = None
        if m is None:
            if len(self.members) >= self.max_members:
                return events  # full: a real member gets in once a silent one fails
            self.members[robot] = Member(
                robot, incarnation, now, repo_version, busy, beat, now, beat
            )
            events.append(TeamEvent.JOINED)
            return events
        m.last_seen = m.last_direct = max(m.last_direct, now)
        m.beat = max(m.beat, beat)
        self._clear(m)
        if beat < m.state_beat:
            return events  # reordered: an older word of its state than the one we hold
        m.state_beat = beat
        if m.repo_version != repo_version:
            m.repo_version = repo_version
            events.append(TeamEvent.CHANGED)
        if m.busy != busy:
            m.busy = busy
            if not busy:
                events.append(TeamEvent.FREED)
        return events

    def suspect(self, robot: str, incarnation: int, beat: int, by: str, now: float) -> bool:
        """``by`` suspects ``robot`` failed at ``beat``: True if this started a suspicion
        or added a suspector. A suspicion of an older beat than we know (refuted already),
        of another life or of a robot that is no member changes nothing."""
        m = self.members.get(robot)
        if m is None or m.incarnation != incarnation or beat < m.beat:
            return False
        s = m.suspicion
        if s is None or beat > s.beat:
            m.beat = beat
            m.suspicion = self.suspected[robot] = Suspicion(beat, now, [by])
            return True
        if not by or by in s.by or len(s.by) >= MAX_SUSPECTORS:
            return False
        s.by.append(by)
        return True

    def hearsay(
        self, robot: str, incarnation: int, beat: int, now: float, *, window_s: float
    ) -> Hearsay:
        """A teammate passes on that ``robot`` was alive at ``beat``. A newer beat of the
        life we know refutes a suspicion of an older one, but only within ``window_s`` of
        our last direct word from it: a teammate lying about a dead robot cannot keep it
        alive past that."""
        if robot == self.robot:
            return Hearsay.NOTHING
        m = self.members.get(robot)
        if m is None:
            return Hearsay.UNKNOWN
        if m.incarnation != incarnation or beat <= m.beat or now - m.last_direct > window_s:
            return Hearsay.NOTHING
        m.beat = beat
        if m.suspicion is not None and beat > m.suspicion.beat:
            self._clear(m)
        return Hearsay.NEWS

    def goodbye(self, robot: str, incarnation: int) -> bool:
        """Whether ``robot`` left (a goodbye of an older incarnation changes nothing)."""
        m = self.members.get(robot)
        if m is None or m.incarnation != incarnation:
            return False
        self._remove(robot)
        return True

    def expire(self, now: float, timeout_s: Callable[[Suspicion], float]) -> list[str]:
        """Members whose suspicion outlived ``timeout_s(suspicion)`` unrefuted, removed
        and returned (declared failed), oldest suspicion first."""
        gone = [r for r, s in self.suspected.items() if now - s.since >= timeout_s(s)]
        for robot in gone:
            self._remove(robot)
        return gone

    def _clear(self, m: Member) -> None:
        if m.suspicion is not None:
            m.suspicion = None
            self.suspected.pop(m.robot, None)

    def _remove(self, robot: str) -> None:
        del self.members[robot]
        self.suspected.pop(robot, None)
