"""Team membership: robots announce themselves by heartbeat; joins, leaves and silent
failures are detected here and reported to local listeners.

A robot needs one reachable teammate (a seed) to join: the seed welcomes it with the
team's :class:`~btcap.team.messages.Roster`, the newcomer beats to each teammate, and they
welcome it in turn. Past ``fanout`` peers, heartbeats go to ``fanout`` of them per period
and carry what their sender heard of others (:mod:`btcap.team.core.gossip`); a robot that
teammates mention but that cannot be reached is asked about (a roster request).
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable

from btcap.actors import Actor, Address, Supervision, handler
from btcap.team.core.gossip import BeatPlan, Introductions, Turns, detection_periods
from btcap.team.core.members import Member, MemberTable, TeamEvent
from btcap.team.ids import ExecutionId
from btcap.team.messages import (
    Activity,
    ActivityQuery,
    Contact,
    Goodbye,
    Heard,
    Heartbeat,
    Roster,
    RosterRequest,
)
from btcap.team.settings import Timing
from btcap.transports.log import get_logger, worth_logging

__all__ = ["Member", "Membership", "TeamEvent"]

log = get_logger("btcap.team")


Listener = Callable[[TeamEvent, str], None]
_DEFAULT = Timing()


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
        heartbeat_s: float = _DEFAULT.heartbeat_s,
        failure_timeout_s: float = _DEFAULT.failure_timeout_s,
        repo_version: Callable[[], int] = lambda: 0,
        busy: Callable[[], bool] = lambda: False,
        activity: Callable[[], tuple[list[ExecutionId], list[ExecutionId]]] = lambda: ([], []),
        fanout: int = _DEFAULT.heartbeat_fanout,
    ) -> None:
        super().__init__()
        # The settings' own checks (bounds, failure_timeout_s > heartbeat_s): ValueError.
        Timing(
            heartbeat_s=heartbeat_s, failure_timeout_s=failure_timeout_s, heartbeat_fanout=fanout
        )
        self.robot = robot
        self.incarnation = time.time_ns()
        self.heartbeat_s = heartbeat_s
        self.failure_timeout_s = failure_timeout_s
        self._repo_version = repo_version
        self._body_busy = busy
        self._activity = activity
        self.table = MemberTable(robot, failure_timeout_s)
        self.refused = 0  #: heartbeats and goodbyes sent in another robot's name
        self.fanout = fanout
        self.beat = 0  #: heartbeats sent in this incarnation
        # Seeded by name: the same team beats in the same order every run (the fast sim).
        self._plan = BeatPlan(fanout, random.Random(f"targets {robot}"))
        self._mentions = Turns(random.Random(f"mentions {robot}"))
        self._asked = Introductions(failure_timeout_s)
        #: Whose roster we take, until when: one that just met us (its welcome) or that
        #: we asked; nobody else may make us dial endpoints of its choosing.
        self._rosters_due: dict[str, float] = {}
        self._was_busy = False
        self._warned_size = 0
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
        """Beat to every peer at once (after a capability change, or to speed up joins)."""
        self.system.broadcast(self.PATH, self._heartbeat(self._body_busy(), heard=False))

    def _heartbeat(self, busy: bool, *, heard: bool) -> Heartbeat:
        mentions: list[Heard] = []
        if heard:
            members, now = self.table.members, self.system.clock.now()
            for robot in self._mentions.take(members, self.fanout):
                m = members[robot]
                age_ms = max(0, round(1000 * (now - m.last_seen)))
                mentions.append(Heard(robot, m.incarnation, m.beat, age_ms))
        version = self._repo_version()
        return Heartbeat(self.robot, self.incarnation, version, busy, self.beat, mentions)

    def _beat_to(self, robot: str) -> None:
        self.system.tell(Address(robot, self.PATH), self._heartbeat(self._body_busy(), heard=False))

    async def _beat(self) -> None:
        clock = self.system.clock
        while True:
            self._periodic_beat()
            self.check(clock.now())
            await clock.sleep(self.heartbeat_s)

    def _periodic_beat(self) -> None:
        """To every peer in a small team or when this robot came free or busy; otherwise
        as :class:`~btcap.team.core.gossip.BeatPlan` says."""
        self.beat += 1
        transport = self.system.transport
        peers = transport.peers() if transport is not None else frozenset()
        busy = self._body_busy()
        plan = self._plan.next(self.table.members, peers)
        if plan.everyone or busy != self._was_busy:
            self._was_busy = busy
            self.system.broadcast(self.PATH, self._heartbeat(busy, heard=False))
            return
        msg = self._heartbeat(busy, heard=plan.heard)
        for peer in plan.to:
            self.system.tell(Address(peer, self.PATH), msg)

    def check(self, now: float) -> None:
        """Declare members failed whose heartbeats stopped."""
        for robot in self.table.expire(now):
            self._emit(TeamEvent.FAILED, robot)

    # -- messages ---------------------------------------------------------------------
    def _speaks_for_itself(self, robot: str, msg: Heartbeat | Goodbye) -> bool:
        """A robot speaks only for itself: the transport authenticated the sender."""
        if robot == self.sender:
            return True
        return self._refuse(msg, claims=robot[:64])

    def _refuse(self, msg: object, **why: str) -> bool:
        """Count and (at a falling rate) log a refused message; False, for the caller."""
        self.refused += 1
        if worth_logging(self.refused):
            log.warning(
                "team.refused",
                robot=self.robot,
                sender=self.sender,
                message=type(msg).__name__,
                count=self.refused,
                **why,
            )
        return False

    @handler
    def on_heartbeat(self, msg: Heartbeat) -> None:
        if not self._speaks_for_itself(msg.robot, msg):
            return
        now = self.system.clock.now()
        events = self.table.heartbeat(
            msg.robot, msg.incarnation, msg.repo_version, now, msg.busy, msg.beat
        )
        for event in events:
            self._emit(event, msg.robot)
        if TeamEvent.JOINED in events:
            self._expect_roster(msg.robot, now)
            self._welcome(msg.robot)
        if msg.heard and msg.robot in self.table.members:
            self._hearsay(msg, now)

    def _welcome(self, robot: str) -> None:
        """Let a newcomer know us at once, and whom else to meet."""
        self._beat_to(robot)
        transport = self.system.transport
        if transport is None:
            return
        contacts = [
            Contact(r, endpoint)
            for r in self.table.members
            if r != robot and (endpoint := transport.endpoint_of(r)) is not None
        ]
        if contacts:
            self.system.tell(Address(robot, self.PATH), Roster(contacts))
        team = len(self.table.members) + 1
        periods = detection_periods(team, self.fanout)
        if self.failure_timeout_s < periods * self.heartbeat_s and team >= 2 * self._warned_size:
            self._warned_size = team
            log.warning(
                "team.timeout_short",
                robot=self.robot,
                team=team,
                failure_timeout_s=self.failure_timeout_s,
                advised_s=round(periods * self.heartbeat_s, 3),
                detail="false failures likely: raise failure_timeout_s or the fanout",
            )

    def _hearsay(self, msg: Heartbeat, now: float) -> None:
        """Fresh beats keep teammates alive; robots we do not know yet get a heartbeat if we
        can reach them, else the sender is asked where they are."""
        # Its own beats reach us every ceil(members / fanout) periods at worst: hearsay
        # bridges twice that, never more (a lying teammate cannot keep it alive).
        gap = math.ceil(len(self.table.members) / self.fanout) * self.heartbeat_s
        limit = self.failure_timeout_s + 2 * gap
        unknown = [
            h.robot
            for h in msg.heard[: 4 * self.fanout]  # more than we ever send: ignored
            if self.table.hearsay(
                h.robot, h.incarnation, h.beat, now, h.age_ms / 1000, limit_s=limit
            )
        ]
        due = self._asked.due(unknown, now) if unknown else []
        if not due:
            return
        transport = self.system.transport
        reachable = transport.peers() if transport is not None else frozenset()
        for robot in due:
            if robot in reachable:
                self._beat_to(robot)
        ask = [r for r in due if r not in reachable]
        if ask:
            self._expect_roster(msg.robot, now)
            self.system.tell(Address(msg.robot, self.PATH), RosterRequest(ask))

    @handler
    def on_roster_request(self, msg: RosterRequest) -> None:
        transport = self.system.transport
        if not self._from_member(msg) or transport is None:
            return
        contacts = []
        for robot in msg.robots[: 4 * self.fanout]:
            endpoint = transport.endpoint_of(robot) if robot in self.table.members else None
            if endpoint is not None:
                contacts.append(Contact(robot, endpoint))
        if contacts:
            self.system.tell(Address(self.sender, self.PATH), Roster(contacts))

    @handler
    def on_roster(self, msg: Roster) -> None:
        """Dial the teammates named (a hint: with keys, only the real one completes the
        handshake) and beat to each, so it welcomes us."""
        transport = self.system.transport
        if not self._from_member(msg) or transport is None:
            return
        due = self._rosters_due.pop(self.sender, None)
        if due is None or self.system.clock.now() > due:
            self._refuse(msg, detail="a roster nobody asked for")
            return
        for c in msg.contacts[: self.table.max_members]:
            known = c.robot == self.robot or c.robot in self.table.members
            if not known and transport.introduce(c.robot, c.endpoint):
                self._beat_to(c.robot)

    @handler
    def on_activity_query(self, msg: ActivityQuery) -> Activity | None:
        if not self._from_member(msg):
            return None
        running, queued = self._activity()
        return Activity(self.robot, running, queued)

    def _expect_roster(self, robot: str, now: float) -> None:
        due = self._rosters_due
        for r in [r for r, until in due.items() if until < now or r not in self.table.members]:
            del due[r]
        due[robot] = now + self.failure_timeout_s

    def _from_member(self, msg: Roster | RosterRequest | ActivityQuery) -> bool:
        if self.sender in self.table.members:
            return True
        return self._refuse(msg, detail="not a member")

    @handler
    def on_goodbye(self, msg: Goodbye) -> None:
        if self._speaks_for_itself(msg.robot, msg) and self.table.goodbye(
            msg.robot, msg.incarnation
        ):
            self._emit(TeamEvent.LEFT, msg.robot)
