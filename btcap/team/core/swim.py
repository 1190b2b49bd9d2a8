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

import random
from collections.abc import Iterable
from dataclasses import dataclass, field

from btcap.team.core.gossip import ProbeOrder, Rumours
from btcap.team.core.members import Hearsay, Member, MemberTable, Suspicion, TeamEvent
from btcap.team.core.newcomers import Newcomers
from btcap.team.core.timeouts import ALPHA, BETA, MAX_HEALTH, MAX_RELAYS, SwimParams
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


@dataclass(slots=True)
class Step:
    """What one input made the protocol do: messages to send (to a robot's membership),
    team events in order, robots mentioned that are no members (worth an introduction)
    and newcomers that answered us (worth a welcome)."""

    sends: list[tuple[str, Message]] = field(default_factory=list)
    events: list[tuple[TeamEvent, str]] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)
    confirmed: list[str] = field(default_factory=list)


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
        self.forgotten = 0  #: members forgotten without ever answering us
        self.newcomers = Newcomers(rng)
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
        self._conclude(now, step)
        for robot in self.table.expire(now, self.timeout_of):
            self.rumours.drop(robot)
            step.events.append((TeamEvent.FAILED, robot))
        for robot in self.newcomers.silent(self.members, now, self.params.forget_s(self.team())):
            self.table.goodbye(robot, self.members[robot].incarnation)
            self.rumours.drop(robot)
            self.forgotten += 1
            step.events.append((TeamEvent.FAILED, robot))
        for robot, nonce in self.newcomers.due(self.members, now, self.period_s):
            step.sends.append((robot, self.heartbeat(to=robot, probe=nonce)))
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
        if probe is None or probe.acked or probe.helpers or probe.target in self.newcomers:
            return step  # (nobody else knows a member that never answered us)
        others = [r for r in self.members if r != probe.target and r not in self.newcomers]
        k = min(self.params.indirect, len(others))
        probe.helpers = tuple(self._rng.sample(sorted(others), k)) if k else ()
        for helper in probe.helpers:
            step.sends.append((helper, ProbeRequest(probe.target, probe.number)))
        return step

    def _conclude(self, now: float, step: Step) -> None:
        probe, self._probe = self._probe, None
        if probe is None:
            return
        m = self.members.get(probe.target)
        if probe.acked:
            self.health = max(self.health - 1, 0)
            # (a newcomer that left since it answered is no member to pass on)
            if self.newcomers.confirm(probe.target) and m is not None:
                self._confirmed(probe.target, step)
            return
        if m is None or m.robot in self.newcomers:
            return  # its silence says nothing of us, and it is forgotten unless it answers
        if m.suspicion is None:
            # The first to find it silent may be the one whose network is failing
            # (Lifeguard: slow down, by each helper that did not even say it was trying;
            # by one when there was none to ask); confirming others' suspicion is no sign.
            missing = len(probe.helpers) - len(probe.nacked) if probe.helpers else 1
            self.health = min(self.health + missing, MAX_HEALTH)
        self._suspect(m, now, step)

    def _suspect(self, m: Member, now: float, step: Step) -> None:
        new = m.robot not in self.table.suspected
        if self.table.suspect(m.robot, m.incarnation, m.beat, self.robot, now):
            s = m.suspicion
            assert s is not None
            self.rumours.add(Heard(m.robot, m.incarnation, s.beat, 0, True, self.robot))
            if new:
                step.events.append((TeamEvent.SUSPECTED, m.robot))

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
        nonce = 0  # a newcomer is probed at once; passed on once it answers
        if events and events[-1] is TeamEvent.JOINED:
            nonce = self.newcomers.joined(robot, now)
        elif news is not None and news.suspect and robot not in self.table.suspected:
            self.rumours.drop(robot)  # heard it ourselves: stop spreading the doubt
        step.events.extend((event, robot) for event in events)
        # Of others, what a member says counts once it answered us; of us, always.
        self._news(robot, msg.heard, now, step, robot in self.newcomers)
        member = robot in self.members
        if (msg.probe or nonce) and member:
            step.sends.append((robot, self.heartbeat(to=robot, probe=nonce, ack=msg.probe)))
        if msg.ack and member:
            self._acked(robot, msg.ack, step)
        return step

    def _confirmed(self, robot: str, step: Step) -> None:
        """A newcomer answered us: others may not know it yet."""
        m = self.members[robot]
        self.rumours.add(Heard(robot, m.incarnation, m.beat))
        step.confirmed.append(robot)

    def _acked(self, robot: str, number: int, step: Step) -> None:
        probe = self._probe
        if probe is not None and probe.number == number and probe.target == robot:
            probe.acked = True
        if self.newcomers.answered(robot, number):
            self._confirmed(robot, step)
        relay = self._relays.pop(number, None)
        if relay is not None and relay.target == robot:
            m = self.members[robot]
            vouch = Vouch(robot, relay.number, m.incarnation, m.beat)
            step.sends.append((relay.requester, vouch))

    def _news(
        self, sender: str, heard: Iterable[Heard], now: float, step: Step, unconfirmed: bool
    ) -> None:
        team = self.team()
        window = self.params.hearsay_window_s(team)
        for n, h in enumerate(heard):
            if n >= 4 * self.params.news:
                break  # more than anybody sends: ignored
            if h.robot == self.robot:
                if h.suspect and h.incarnation == self.incarnation:
                    self._refute(h.beat)
                continue
            if unconfirmed:
                continue
            if h.suspect:
                # A robot speaks only for itself: news of a suspicion says its sender holds
                # it (honest robots pass on only what they hold), so the sender counts as a
                # suspector, never the robot named in ``by`` (else a liar could name others
                # and bring every suspicion to its shortest timeout). Except our own
                # suspicion passed back to us: those we told confirm nothing (its echoes
                # brought one lossy probe's suspicion to the floor, ahead of the refutation).
                by = "" if h.by == self.robot else sender
                new = h.robot not in self.table.suspected
                if self.table.suspect(h.robot, h.incarnation, h.beat, by, now):
                    self.rumours.add(Heard(h.robot, h.incarnation, h.beat, 0, True, h.by))
                    if new:
                        step.events.append((TeamEvent.SUSPECTED, h.robot))
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
        if sender in self.newcomers:
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

    def unreachable(self, robot: str, now: float) -> Step:
        """Nobody listens where ``robot`` said (the transport cannot connect): suspect it
        now, not in its round-robin turn; refuted by its own newer beat, as any other."""
        step = Step()
        m = self.members.get(robot)
        if m is not None and m.suspicion is None and robot not in self.newcomers:
            self._suspect(m, now, step)
        return step

    def on_goodbye(self, robot: str, incarnation: int) -> Step:
        step = Step()
        if self.table.goodbye(robot, incarnation):
            self.rumours.drop(robot)
            step.events.append((TeamEvent.LEFT, robot))
        return step
