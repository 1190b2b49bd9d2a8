"""Failure detection that needs no tuning: SWIM with Lifeguard's refinements (sans-IO).

Each period (``period_s``, the ``heartbeat_s`` setting) a robot probes one member
(:class:`~btcap.team.core.gossip.ProbeOrder`) with a heartbeat carrying news; it answers
at once. No answer within the probe timeout: ``indirect`` others are asked to probe it
(:class:`~btcap.team.messages.ProbeRequest`; a :class:`~btcap.team.messages.Vouch` is an
answer). Silent at the period's end (or unreachable for the transport): *suspected*, and
the suspicion spreads. Holders of a suspicion probe the suspect every other period (an
answer clears it there and carries the refutation) and run their own timer
(:meth:`SwimParams.suspicion_s`: ``alpha·log10(team)`` to ``beta·alpha·log10(team)``
periods, never below ``floor_s``, shorter with more independent confirmations); each
declares the member failed alone. No message says "X is dead": nobody can kill a live
robot by saying so. A suspected robot refutes with a newer ``beat`` (the version of what
it says of itself in this life); a refutation passed on by others counts only within
:meth:`SwimParams.hearsay_window_s` of our last direct word from the robot.

Lifeguard's local health: a robot whose probes go unanswered while its helpers do not
even say they are trying (a nack: a :class:`Vouch` with ``answered`` false), or that must
refute suspicions of itself, is probably the slow one: its period and probe timeout grow
by ``1 + health`` (health up to :data:`MAX_HEALTH`). Design and bound: docs/membership.md.
"""

from __future__ import annotations

import math
import random
from collections.abc import Iterable
from dataclasses import dataclass, field

from btcap.team.core.gossip import ProbeOrder, Rumours
from btcap.team.core.members import Hearsay, Member, MemberTable, Suspicion, TeamEvent
from btcap.team.messages import Heard, Heartbeat, ProbeRequest, Vouch
from btcap.transports.message import Message

__all__ = [
    "ALPHA",
    "BETA",
    "MAX_HEALTH",
    "Step",
    "Swim",
    "SwimParams",
]

ALPHA = 4.0  #: suspicion timeout, in periods per decade of team size (Lifeguard's alpha)
BETA = 6.0  #: the longest suspicion timeout, in shortest ones (Lifeguard's beta)
CONFIRMATIONS = 3  #: independent confirmations that bring a suspicion to its shortest
RETRANSMIT = 4  #: each news item is passed on RETRANSMIT·⌈log10(team + 1)⌉ times (lambda)
MAX_HEALTH = 8  #: the local health multiplier's ceiling (Lifeguard's awareness)
MAX_RELAYS = 64  #: indirect probes run for others at once (a flood of requests is dropped)


@dataclass(frozen=True, slots=True)
class SwimParams:
    """The protocol's settings; everything else scales with the team by itself."""

    period_s: float  #: a probe per period (the ``heartbeat_s`` setting)
    floor_s: float  #: the shortest suspicion timeout (the ``failure_timeout_s`` setting)
    news: int = 8  #: news items per message (the ``heartbeat_fanout`` setting)
    indirect: int = 3  #: members asked to probe an unanswering one (SWIM's k)
    max_members: int = 1024

    def __post_init__(self) -> None:
        if not self.floor_s > self.period_s:
            raise ValueError("failure_timeout_s: must exceed heartbeat_s")

    @property
    def probe_timeout_s(self) -> float:
        """How long a direct probe waits before asking others (half a period)."""
        return self.period_s / 2

    def suspicion_bounds(self, team: int) -> tuple[float, float]:
        """The shortest and longest suspicion timeouts in a team of ``team`` robots:
        ``alpha·log10(team)`` periods and beta times that, neither below the floor (a floor
        the user set is what they get where it is longer than the scaled timeouts)."""
        scaled = ALPHA * math.log10(max(team, 1)) * self.period_s
        lo = max(self.floor_s, scaled)
        return lo, max(lo, BETA * scaled)

    def suspicion_s(self, team: int, confirmations: int) -> float:
        """Lifeguard's timeout: the longest with no independent confirmation, down to the
        shortest with :data:`CONFIRMATIONS` of them (logarithmically)."""
        lo, hi = self.suspicion_bounds(team)
        k = min(CONFIRMATIONS, team - 2)
        if k < 1:
            return lo
        done = math.log(min(confirmations, k) + 1) / math.log(k + 1)
        return max(lo, hi - (hi - lo) * done)

    def retransmits(self, team: int) -> int:
        """How many times each news item is passed on."""
        return RETRANSMIT * max(1, math.ceil(math.log10(team + 1)))

    def hearsay_window_s(self, team: int) -> float:
        """A refutation passed on by others counts only this long after our last direct
        word from the robot: the longest suspicion plus two periods."""
        return self.suspicion_bounds(team)[1] + 2 * self.period_s

    def detection_bound_s(self, team: int) -> float:
        """The stated bound on detecting a dead robot once someone probed it: the probe's
        period, the suspicion's spread (every news item is sent ``retransmits`` times, one
        a period at least) and the longest suspicion timeout. O(log team)."""
        return self.period_s * (2 + self.retransmits(team)) + self.suspicion_bounds(team)[1]


@dataclass(slots=True)
class Step:
    """What one input made the protocol do: messages to send (to a robot's membership),
    team events in order, and robots mentioned that are no members (worth an
    introduction)."""

    sends: list[tuple[str, Message]] = field(default_factory=list)
    events: list[tuple[TeamEvent, str]] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)


@dataclass(slots=True)
class _Probe:
    target: str
    number: int
    acked: bool = False
    helpers: tuple[str, ...] = ()
    nacked: set[str] = field(default_factory=set)  #: helpers that said they are trying


@dataclass(slots=True)
class _Relay:
    requester: str
    number: int  #: the requester's probe number
    target: str
    until: float


class Swim:
    """One robot's failure detector: feed it the clock (:meth:`tick`, :meth:`timeout`)
    and its teammates' messages (``sender`` already authenticated by the transport); it
    returns what to send and what changed. ``repo_version``/``busy`` are this robot's
    own state, set with :meth:`set_state`."""

    def __init__(
        self,
        robot: str,
        incarnation: int,
        params: SwimParams,
        rng: random.Random,
        *,
        repo_version: int = 0,
        busy: bool = False,
    ) -> None:
        self.robot = robot
        self.incarnation = incarnation
        self.params = params
        self.table = MemberTable(robot, max_members=params.max_members)
        self.rumours = Rumours(params.max_members + 1)
        self.beat = 0  #: the version of what this robot says of itself, in this life
        self.health = 0  #: Lifeguard's local health multiplier, 0 (healthy) to MAX_HEALTH
        self.repo_version = repo_version
        self.busy = busy
        self.refuted = 0  #: suspicions of this robot it refuted
        self._rng = rng
        self._order = ProbeOrder(rng)
        self._probe: _Probe | None = None
        self._numbers = 0
        self._relays: dict[int, _Relay] = {}
        self._suspect_turn = False  #: whether this period probes a suspect

    # -- reading -----------------------------------------------------------------------
    @property
    def members(self) -> dict[str, Member]:
        return self.table.members

    def team(self) -> int:
        """The team's size as this robot sees it, itself included."""
        return len(self.table.members) + 1

    @property
    def period_s(self) -> float:
        """This period's length: longer while this robot's own health is poor."""
        return self.params.period_s * (1 + self.health)

    @property
    def probe_timeout_s(self) -> float:
        return self.params.probe_timeout_s * (1 + self.health)

    def timeout_of(self, suspicion: Suspicion) -> float:
        return self.params.suspicion_s(self.team(), suspicion.confirmations)

    # -- this robot ---------------------------------------------------------------------
    def set_state(self, repo_version: int, busy: bool) -> bool:
        """This robot's own state; True if it changed (then tell everyone: its beat grew,
        so the news outranks any older word of it)."""
        if (repo_version, busy) == (self.repo_version, self.busy):
            return False
        self.repo_version, self.busy = repo_version, busy
        self.beat += 1
        return True

    def heartbeat(self, *, to: str | None = None, probe: int = 0, ack: int = 0) -> Heartbeat:
        """A message of this robot about itself, with news piggybacked (news of ``to``
        first: a suspected robot learns of it from the probe that checks it)."""
        p = self.params
        if to is not None and (m := self.members.get(to)) and m.suspicion is not None:
            # To a suspect: only its suspicion (news passed to a dead robot is wasted).
            heard = [Heard(to, m.incarnation, m.suspicion.beat, 0, True, self.robot)]
        else:
            heard = self.rumours.take(p.news, p.retransmits(self.team()), first=to)
        return Heartbeat(
            self.robot,
            self.incarnation,
            self.repo_version,
            self.busy,
            self.beat,
            heard,
            probe,
            ack,
        )

    # -- the clock ----------------------------------------------------------------------
    def tick(self, now: float) -> Step:
        """A period starts: the last probe concludes, suspicions that ran out become
        failures, and the next member is probed."""
        step = Step()
        self._conclude(now)
        for robot in self.table.expire(now, self.timeout_of):
            self.rumours.drop(robot)
            step.events.append((TeamEvent.FAILED, robot))
        self._relays = {n: r for n, r in self._relays.items() if r.until > now}
        target = self._next_target(now)
        if target is not None:
            self._numbers += 1
            self._probe = _Probe(target, self._numbers)
            step.sends.append((target, self.heartbeat(to=target, probe=self._numbers)))
        if target in self.table.suspected and len(self.rumours):
            # A probe of a suspect carries only its suspicion: the news goes on to the
            # round robin's member, so it keeps spreading while everybody checks.
            gossip = self._order.next(self.members)
            if gossip is not None and gossip != target:
                step.sends.append((gossip, self.heartbeat(to=gossip)))
        return step

    def timeout(self, now: float) -> Step:
        """The probe timeout passed: if the target has not answered, ask others."""
        step = Step()
        probe = self._probe
        if probe is None or probe.acked or probe.helpers:
            return step
        others = [r for r in self.members if r != probe.target]
        k = min(self.params.indirect, len(others))
        probe.helpers = tuple(self._rng.sample(sorted(others), k)) if k else ()
        for helper in probe.helpers:
            step.sends.append((helper, ProbeRequest(probe.target, probe.number)))
        return step

    def _conclude(self, now: float) -> None:
        probe, self._probe = self._probe, None
        if probe is None:
            return
        m = self.members.get(probe.target)
        if probe.acked:
            self.health = max(self.health - 1, 0)
            return
        if m is None:
            return
        if m.suspicion is None:
            # The first to find it silent may be the one whose network is failing
            # (Lifeguard: slow down, by each helper that did not even say it was trying;
            # by one when there was none to ask); confirming others' suspicion is no sign.
            missing = len(probe.helpers) - len(probe.nacked) if probe.helpers else 1
            self.health = min(self.health + missing, MAX_HEALTH)
        self._suspect(m, now)

    def _suspect(self, m: Member, now: float) -> None:
        if self.table.suspect(m.robot, m.incarnation, m.beat, self.robot, now):
            s = m.suspicion
            assert s is not None
            self.rumours.add(Heard(m.robot, m.incarnation, s.beat, 0, True, self.robot))

    def _next_target(self, now: float) -> str | None:
        """Every other period, a suspected member, the one we probed least recently: an
        answer to us clears the suspicion here, and carries the robot's refutation;
        silence confirms it. Otherwise the round robin, which must go on: several robots
        that die at once are found one after the other, not one per suspicion."""
        suspected = self.table.suspected
        self._suspect_turn = not self._suspect_turn and bool(suspected)
        if self._suspect_turn:
            robot = min(suspected, key=lambda r: suspected[r].probed_at)
            suspected[robot].probed_at = now
            return robot
        return self._order.next(self.members)

    # -- messages -------------------------------------------------------------------------
    def on_heartbeat(self, msg: Heartbeat, now: float) -> Step:
        """A message of ``msg.robot`` itself (the caller checked that it sent it)."""
        step = Step()
        robot = msg.robot
        if robot == self.robot:
            return step
        events = self.table.heartbeat(
            robot, msg.incarnation, msg.repo_version, now, msg.busy, msg.beat
        )
        news = self.rumours.about(robot)
        if events and events[-1] is TeamEvent.JOINED:  # passed on: others may not know it
            self.rumours.add(Heard(robot, msg.incarnation, msg.beat))
        elif news is not None and news.suspect and robot not in self.table.suspected:
            self.rumours.drop(robot)  # heard it ourselves: stop spreading the doubt
        step.events.extend((event, robot) for event in events)
        self._news(robot, msg.heard, now, step)
        member = robot in self.members
        if msg.probe and member:
            step.sends.append((robot, self.heartbeat(to=robot, ack=msg.probe)))
        if msg.ack and member:
            self._acked(robot, msg.ack, step)
        return step

    def _acked(self, robot: str, number: int, step: Step) -> None:
        probe = self._probe
        if probe is not None and probe.number == number and probe.target == robot:
            probe.acked = True
        relay = self._relays.pop(number, None)
        if relay is not None and relay.target == robot:
            m = self.members[robot]
            vouch = Vouch(robot, relay.number, m.incarnation, m.beat)
            step.sends.append((relay.requester, vouch))

    def _news(self, sender: str, heard: Iterable[Heard], now: float, step: Step) -> None:
        team = self.team()
        window = self.params.hearsay_window_s(team)
        for n, h in enumerate(heard):
            if n >= 4 * self.params.news:
                break  # more than anybody sends: ignored
            if h.robot == self.robot:
                if h.suspect and h.incarnation == self.incarnation:
                    self._refute(h.beat)
                continue
            if h.suspect:
                # A robot speaks only for itself: news of a suspicion says its sender holds
                # it (honest robots pass on only what they hold), so the sender counts as a
                # suspector, never the robot named in ``by`` (else a liar could name others
                # and bring every suspicion to its shortest timeout).
                if self.table.suspect(h.robot, h.incarnation, h.beat, sender, now):
                    self.rumours.add(Heard(h.robot, h.incarnation, h.beat, 0, True, h.by))
                continue
            result = self.table.hearsay(h.robot, h.incarnation, h.beat, now, window_s=window)
            if result is Hearsay.NEWS:
                self.rumours.add(Heard(h.robot, h.incarnation, h.beat))
            elif result is Hearsay.UNKNOWN:
                step.unknown.append(h.robot)

    def _refute(self, beat: int) -> None:
        """We are suspected at ``beat``: a newer beat of ours outranks it everywhere."""
        if beat >= self.beat:
            self.beat = beat + 1
            self.refuted += 1
            self.health = min(self.health + 1, MAX_HEALTH)
        elif self.rumours.about(self.robot) is not None:
            return  # refuted already, and still spreading
        self.rumours.add(Heard(self.robot, self.incarnation, self.beat))

    def on_probe_request(self, sender: str, msg: ProbeRequest, now: float) -> Step:
        """A member asks us to probe ``msg.target`` for it (a member too, else nothing)."""
        step = Step()
        if sender not in self.members or msg.target not in self.members or sender == msg.target:
            return step
        if len(self._relays) >= MAX_RELAYS:
            return step
        self._numbers += 1
        until = now + self.period_s
        self._relays[self._numbers] = _Relay(sender, msg.probe, msg.target, until)
        step.sends.append((msg.target, self.heartbeat(to=msg.target, probe=self._numbers)))
        step.sends.append((sender, Vouch(msg.target, msg.probe, 0, 0, answered=False)))
        return step

    def on_vouch(self, sender: str, msg: Vouch, now: float) -> Step:
        """A member we asked says the target answered it: our probe succeeded. A vouch
        answers our probe only; it refutes no suspicion (only the robot's own beat does)."""
        probe = self._probe
        if (
            probe is not None
            and sender in probe.helpers
            and msg.probe == probe.number
            and msg.target == probe.target
        ):
            if msg.answered:
                probe.acked = True
            else:
                probe.nacked.add(sender)
        return Step()

    def unreachable(self, robot: str, now: float) -> None:
        """Nobody listens where ``robot`` said (the transport cannot connect): suspect it
        now, not in its round-robin turn; refuted by its own newer beat, as any other."""
        m = self.members.get(robot)
        if m is not None and m.suspicion is None:
            self._suspect(m, now)

    def on_goodbye(self, robot: str, incarnation: int) -> Step:
        step = Step()
        if self.table.goodbye(robot, incarnation):
            self.rumours.drop(robot)
            step.events.append((TeamEvent.LEFT, robot))
        return step
