"""Team membership: robots probe each other (SWIM with Lifeguard's refinements); joins,
leaves and failures are detected here and reported to local listeners.

A robot needs one reachable teammate (a seed) to join: the seed welcomes it with the
team's :class:`~btcap.team.messages.Roster`, the newcomer beats to each teammate, and they
welcome it in turn. From then on each robot probes one member per period and passes news
on (joins, suspicions, refutations); the decisions are :mod:`btcap.team.core.swim`'s. A
robot that teammates mention but that cannot be reached is asked about (a roster
request). Peers that are no members (a seed not met yet, a robot back from a partition)
get a heartbeat in turns, ``fanout`` a period, so they (re)join.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable

from btcap.actors import Actor, Address, Supervision, handler
from btcap.actors.heap import HeapTrim
from btcap.team.core.gossip import Introductions, Turns
from btcap.team.core.members import Member, MemberTable, TeamEvent
from btcap.team.core.swim import Step, Swim, SwimParams
from btcap.team.ids import ExecutionId
from btcap.team.messages import (
    Activity,
    ActivityQuery,
    Contact,
    Goodbye,
    Heartbeat,
    ProbeRequest,
    Roster,
    RosterRequest,
    Vouch,
)
from btcap.team.settings import Timing
from btcap.transports.log import get_logger, worth_logging

__all__ = ["Member", "Membership", "TeamEvent"]

log = get_logger(__name__)


Listener = Callable[[TeamEvent, str], None]
_DEFAULT = Timing()
MAX_ANSWERS_DUE = 3
"""Answers to our roster requests one member may owe us at once (besides its welcome):
what a member can make us dial stays bounded; more questions wait for an answer."""


class Membership(Actor):
    """Probes out, answers in, and a failure detector on clock time.

    The decisions are :class:`~btcap.team.core.swim.Swim`'s; this actor runs its clock,
    sends what it says and tells local listeners what changed.
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
        self.heartbeat_s = heartbeat_s
        self.failure_timeout_s = failure_timeout_s
        self._repo_version = repo_version
        self._body_busy = busy
        self._activity = activity
        params = SwimParams(heartbeat_s, failure_timeout_s, news=fanout)
        # Seeded by name: the same team probes in the same order every run (the fast sim).
        self.swim = Swim(robot, time.time_ns(), params, random.Random(f"probes {robot}"))
        self.refused = 0  #: messages sent in another robot's name, or by strangers
        self.heap = HeapTrim()  #: gives back what forgotten made-up members cost
        self.fanout = fanout
        self._others = Turns(random.Random(f"others {robot}"))
        self._asked = Introductions(failure_timeout_s)
        #: The rosters each member owes us, by deadline: its welcome, once per its join
        #: (no deadline: how soon it learns of us depends on gossip and load), and the
        #: answer to each request we sent it (at most MAX_ANSWERS_DUE at once). Nobody
        #: else may make us dial endpoints of its choosing. Forgotten when it departs.
        self._rosters_due: dict[str, list[float]] = {}
        self._listeners: list[Listener] = []

    @property
    def incarnation(self) -> int:
        """This life's number: larger after every restart (wall-clock nanoseconds)."""
        return self.swim.incarnation

    @incarnation.setter
    def incarnation(self, value: int) -> None:
        # Before it starts only: a deterministic simulation numbers lives itself.
        self.swim.incarnation = value

    @property
    def table(self) -> MemberTable:
        return self.swim.table

    @property
    def beat(self) -> int:
        """The version of what this robot says of itself, in this life."""
        return self.swim.beat

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

    def suspected(self) -> frozenset[str]:
        """The members under suspicion now (still members: they may refute it)."""
        return frozenset(self.table.suspected)

    def _emit(self, event: TeamEvent, robot: str) -> None:
        if event in (TeamEvent.FAILED, TeamEvent.LEFT):
            self._rosters_due.pop(robot, None)  # what its life owed us, it never will
        # routine, not a change
        emit = log.debug if event in (TeamEvent.FREED, TeamEvent.SUSPECTED) else log.info
        emit("team.event", robot=self.robot, change=event.value, member=robot)
        for listener in list(self._listeners):
            try:
                listener(event, robot)
            except Exception as exc:
                log.error("team.listener_failed", robot=self.robot, exc_info=exc)

    # -- life cycle -------------------------------------------------------------------
    def on_start(self) -> None:
        self.swim.set_state(self._repo_version(), self._body_busy())
        self.start_task(self._run(), name=f"membership {self.robot}")

    def on_stop(self) -> None:
        self.heap.cancel()
        system = self._system
        if system is not None and system.transport is not None:
            system.broadcast(self.PATH, Goodbye(self.robot, self.incarnation))

    def beat_now(self) -> None:
        """Tell every peer at once what this robot offers (after a capability change, or
        to speed up joins)."""
        self.swim.set_state(self._repo_version(), self._body_busy())
        self.system.broadcast(self.PATH, self.swim.heartbeat())

    def _beat_to(self, robot: str) -> None:
        self.system.tell(Address(robot, self.PATH), self.swim.heartbeat())

    async def _run(self) -> None:
        clock, swim = self.system.clock, self.swim
        while True:
            self._period(clock.now())
            period, wait = swim.period_s, swim.probe_timeout_s
            await clock.sleep(wait)
            self._apply(swim.timeout(clock.now()), None)
            await clock.sleep(period - wait)

    def _period(self, now: float) -> None:
        """A new period: our own news first (a robot coming free or busy, or offering
        something new, tells every peer at once), then the probe, then a heartbeat to
        peers that are no members, in turns."""
        if self.swim.set_state(self._repo_version(), self._body_busy()):
            self.system.broadcast(self.PATH, self.swim.heartbeat())
        forgotten = self.swim.forgotten
        self._apply(self.swim.tick(now), None)
        if self.swim.forgotten != forgotten:
            self.heap.burst()
        transport = self.system.transport
        if transport is None:
            return
        for robot in transport.unreachable() & self.table.members.keys():
            self._apply(self.swim.unreachable(robot, now), None)
        others = transport.peers() - self.table.members.keys()  # a set operation, in C
        for peer in self._others.take(others, self.fanout) if others else ():
            self._beat_to(peer)

    def check(self, now: float) -> None:
        """Declare members failed whose suspicion ran out unrefuted."""
        for robot in self.table.expire(now, self.swim.timeout_of):
            self.swim.rumours.drop(robot)
            self._emit(TeamEvent.FAILED, robot)

    def _apply(self, step: Step, sender: str | None) -> None:
        """Send what the protocol said, then tell listeners what changed."""
        for to, msg in step.sends:
            self.system.tell(Address(to, self.PATH), msg)
        for event, robot in step.events:
            self._emit(event, robot)
            if event is TeamEvent.JOINED:
                self._rosters_due[robot] = [math.inf]  # its welcome, whenever it comes
        for robot in step.confirmed:  # it answered our probe: worth the team's roster
            self._welcome(robot)
        if step.unknown and sender is not None:
            self._introduce(sender, step.unknown)

    # -- messages ---------------------------------------------------------------------
    def _speaks_for_itself(self, robot: str, msg: Heartbeat | Goodbye) -> bool:
        """A robot speaks only for itself: the transport authenticated the sender."""
        if robot == self.sender:
            return True
        return self._refuse(msg, claims=robot[:64])

    def _refuse(self, msg: object, *, harmless: bool = False, **why: str) -> bool:
        """Count and (at a falling rate) log a refused message; False, for the caller.
        A ``harmless`` one (it could not have made us do anything) is logged at debug."""
        self.refused += 1
        if worth_logging(self.refused):
            (log.debug if harmless else log.warning)(
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
        self._apply(self.swim.on_heartbeat(msg, self.system.clock.now()), msg.robot)

    @handler
    def on_probe_request(self, msg: ProbeRequest) -> None:
        if self._from_member(msg):
            self._apply(self.swim.on_probe_request(self.sender, msg, self.system.clock.now()), None)

    @handler
    def on_vouch(self, msg: Vouch) -> None:
        if self._from_member(msg):
            self._apply(self.swim.on_vouch(self.sender, msg, self.system.clock.now()), None)

    def _welcome(self, robot: str) -> None:
        """Tell a newcomer that answered us whom else to meet (it knows us: the probe it
        answered was our heartbeat). Members that never answered us are not named."""
        transport = self.system.transport
        if transport is None:
            return
        contacts = [
            Contact(r, endpoint)
            for r in self.table.members
            if r != robot
            and r not in self.swim.newcomers
            and (endpoint := transport.endpoint_of(r)) is not None
        ]
        # Sent even when empty: it uses up the one roster the newcomer takes unasked.
        self.system.tell(Address(robot, self.PATH), Roster(contacts))

    def _introduce(self, sender: str, unknown: list[str]) -> None:
        """Robots a member mentions that we do not know get a heartbeat if we can reach
        them (they welcome us), else the member is asked where they are."""
        now = self.system.clock.now()
        transport = self.system.transport
        reachable = transport.peers() if transport is not None else frozenset()
        if not self._may_ask(sender, now):  # the others wait for a member we may ask
            unknown = [r for r in unknown if r in reachable]
        due = self._asked.due(unknown, now)
        for robot in due:
            if robot in reachable:
                self._beat_to(robot)
        ask = [r for r in due if r not in reachable]
        if ask:
            self._rosters_due[sender].append(now + self.failure_timeout_s)
            self.system.tell(Address(sender, self.PATH), RosterRequest(ask))

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
        # Sent even when empty: it is the answer the asker waits for.
        self.system.tell(Address(self.sender, self.PATH), Roster(contacts))

    @handler
    def on_roster(self, msg: Roster) -> None:
        """Dial the teammates named (a hint: with keys, only the real one completes the
        handshake) and beat to each, so it welcomes us."""
        transport = self.system.transport
        if not self._from_member(msg) or transport is None:
            return
        if not self._take_roster(self.sender, self.system.clock.now()):
            # A robot the others failed while it kept them is welcomed again by each:
            # routine, and harmless when the roster names nobody we would dial.
            news = any(self._unknown(c.robot) for c in msg.contacts[: self.table.max_members])
            self._refuse(msg, harmless=not news, detail="a roster nobody asked for")
            return
        for c in msg.contacts[: self.table.max_members]:
            if self._unknown(c.robot) and transport.introduce(c.robot, c.endpoint):
                self._beat_to(c.robot)

    def _unknown(self, robot: str) -> bool:
        return robot != self.robot and robot not in self.table.members

    @handler
    def on_activity_query(self, msg: ActivityQuery) -> Activity | None:
        if not self._from_member(msg):
            return None
        running, queued = self._activity()
        return Activity(self.robot, running, queued)

    def _owed(self, robot: str, now: float) -> list[float]:
        """The deadlines of the rosters ``robot`` (a member) still owes us, late ones
        dropped."""
        owed = self._rosters_due.setdefault(robot, [])
        owed[:] = [until for until in owed if until >= now]
        return owed

    def _may_ask(self, robot: str, now: float) -> bool:
        """Whether a roster request to ``robot`` may go out: a member that does not owe
        us :data:`MAX_ANSWERS_DUE` answers already."""
        if robot not in self.table.members:
            return False
        return sum(until != math.inf for until in self._owed(robot, now)) < MAX_ANSWERS_DUE

    def _take_roster(self, robot: str, now: float) -> bool:
        """Count a roster from ``robot`` against what it owes us, the soonest due first
        (the rosters carry no question: whichever comes, a later one may still be due).
        False: it owes us none."""
        owed = self._owed(robot, now)
        if not owed:
            return False
        owed.remove(min(owed))
        return True

    def _from_member(
        self, msg: Roster | RosterRequest | ActivityQuery | ProbeRequest | Vouch
    ) -> bool:
        if self.sender in self.table.members:
            return True
        return self._refuse(msg, detail="not a member")

    @handler
    def on_goodbye(self, msg: Goodbye) -> None:
        if self._speaks_for_itself(msg.robot, msg):
            self._apply(self.swim.on_goodbye(msg.robot, msg.incarnation), None)
