"""SWIM failure detection on explicit time: probes, indirect probes, suspicion and
refutation, Lifeguard's timeouts, liars, bounds; one robot by hand, then whole teams over
the seeded network of :mod:`btcap.sim.faults.swimnet`."""

from __future__ import annotations

import itertools
import math
import random

import msgspec
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from btcap.sim.faults.swimnet import SwimNet
from btcap.team.core.members import TeamEvent
from btcap.team.core.swim import MAX_RELAYS, Swim, SwimParams
from btcap.team.messages import Heard, Heartbeat, ProbeRequest, Vouch

DEFAULTS = SwimParams(period_s=0.1, floor_s=0.5)  # the library's defaults


def robot(name: str = "a", team: tuple[str, ...] = ("b", "c", "d", "e")) -> Swim:
    """``name`` with ``team`` joined, each answering the probe its join brought."""
    s = Swim(name, 1, DEFAULTS, random.Random(0))
    for other in team:
        [(_, probe)] = s.on_heartbeat(Heartbeat(other, 1, 0), 0.0).sends
        assert isinstance(probe, Heartbeat)
        s.on_heartbeat(Heartbeat(other, 1, 0, ack=probe.probe), 0.0)
    assert len(s.newcomers) == 0
    return s


def test_timeouts_scale_with_the_team_and_the_setting_is_their_floor() -> None:
    p = DEFAULTS
    assert p.suspicion_bounds(10) == (0.5, pytest.approx(2.4))  # 4·log10(10)·0.1 < the floor
    assert SwimParams(5.0, 80.0).suspicion_bounds(4) == (80.0, 80.0)  # a long floor: as set
    lo, hi = p.suspicion_bounds(1000)
    assert (lo, hi) == (pytest.approx(1.2), pytest.approx(7.2))
    assert p.suspicion_s(1000, 0) == pytest.approx(7.2)  # nobody else agrees: the longest
    assert p.suspicion_s(1000, 3) == pytest.approx(1.2)  # three others agree: the shortest
    assert p.suspicion_s(1000, 1) == pytest.approx(7.2 - 6.0 * math.log(2) / math.log(4))
    assert p.suspicion_s(2, 0) == 0.5  # nobody could confirm: the shortest
    assert p.retransmits(10) == 8
    assert p.retransmits(500) == 12
    # the stated detection bound grows with log(team), not with the team
    growth = [p.detection_bound_s(n) for n in (10, 100, 1000, 10000)]
    steps = [b - a for a, b in itertools.pairwise(growth)]
    assert all(s < 3.0 for s in steps)
    assert growth[-1] < 15


def test_a_setting_that_cannot_work_is_refused_with_its_name() -> None:
    with pytest.raises(ValueError, match="failure_timeout_s: must exceed heartbeat_s"):
        SwimParams(period_s=1.0, floor_s=1.0)


def test_an_unanswered_probe_asks_others_then_suspects_and_the_suspect_refutes() -> None:
    a = robot()
    step = a.tick(0.0)
    [(target, ping)] = step.sends
    assert isinstance(ping, Heartbeat)
    assert ping.probe
    step = a.timeout(0.05)
    asked = [to for to, msg in step.sends if isinstance(msg, ProbeRequest)]
    assert len(asked) == 3
    assert target not in asked
    assert a.timeout(0.06).sends == []  # asked once
    a.tick(0.1)  # the period ended in silence: suspected, and the news spreads
    m = a.members[target]
    assert m.suspicion is not None
    assert m.suspicion.by == ["a"]
    # The next ping to the suspect carries the suspicion; the suspect refutes it.
    t = Swim(target, 1, DEFAULTS, random.Random(1))
    t.on_heartbeat(Heartbeat("a", 1, 0), 0.1)
    step = t.on_heartbeat(a.heartbeat(to=target, probe=7), 0.15)
    [(to, ack)] = step.sends
    assert to == "a"
    assert isinstance(ack, Heartbeat)
    assert ack.ack == 7
    assert ack.beat == 1
    assert t.refuted == 1
    a.on_heartbeat(ack, 0.16)
    assert a.members[target].suspicion is None
    assert a.members[target].beat == 1


def test_a_vouch_answers_only_the_probe_it_was_asked_for() -> None:
    team = tuple(f"r{i}" for i in range(8))
    a = robot(team=team)
    [(target, _)] = a.tick(0.0).sends
    helpers = [to for to, _ in a.timeout(0.05).sends]
    stranger = next(r for r in team if r not in helpers and r != target)
    a.on_vouch(stranger, Vouch(target, 1, 1, 0), 0.06)  # not asked
    a.on_vouch(helpers[0], Vouch(target, 99, 1, 0), 0.06)  # another probe
    a.on_vouch(helpers[0], Vouch(stranger, 1, 1, 0), 0.06)  # another target
    a.tick(0.1)
    assert a.members[target].suspicion is not None

    b = robot(team=team)
    [(target, _)] = b.tick(0.0).sends
    helpers = [to for to, _ in b.timeout(0.05).sends]
    b.on_vouch(helpers[0], Vouch(target, 1, 1, 0), 0.06)
    b.tick(0.1)
    assert b.table.suspected == {}


def test_helpers_that_say_they_are_trying_keep_the_prober_healthy() -> None:
    """Lifeguard's nacks: a dead member found by a robot whose helpers answer does not
    slow it down; helpers that stay silent too (its own network failing?) do, by each."""
    team = tuple(f"r{i}" for i in range(8))
    for told, health in ((3, 0), (2, 1), (0, 3)):
        a = robot(team=team)
        target = a.tick(0.0).sends[0][0]
        helpers = [to for to, m in a.timeout(0.05).sends if isinstance(m, ProbeRequest)]
        assert len(helpers) == 3
        number = a.heartbeat(to=target).probe or 1  # our first probe's number
        for helper in helpers[:told]:
            a.on_vouch(helper, Vouch(target, number, 0, 0, answered=False), 0.06)
        if told:  # a helper that says it twice counts once
            a.on_vouch(helpers[0], Vouch(target, number, 0, 0, answered=False), 0.07)
        a.tick(0.1)
        assert a.health == health, told
        assert a.members[target].suspicion is not None  # a nack is no answer


def test_our_suspicion_passed_back_to_us_confirms_nothing() -> None:
    """Lifeguard shortens a suspicion only with independent confirmations: members that
    pass our own suspicion back to us are relays of it, not suspectors. Seed
    16 of the team test (16 robots, 5 % loss): one robot's lossy probe started the only
    real suspicion, its echoes brought it to the floor and the suspect, which refuted,
    was declared failed before its refutation got back."""
    a = robot()
    [(target, _)] = a.tick(0.0).sends
    a.timeout(0.05)
    a.tick(0.1)  # silent: suspected by a alone
    inc = a.members[target].incarnation
    others = [r for r in a.members if r != target]
    for sender in others:
        echo = Heard(target, inc, 0, 0, True, "a")  # ours, passed back to us
        a.on_heartbeat(Heartbeat(sender, 1, 0, heard=[echo]), 0.12)
    s = a.members[target].suspicion
    assert s is not None
    assert s.confirmations == 0
    hi = DEFAULTS.suspicion_bounds(a.team())[1]
    assert a.timeout_of(s) == pytest.approx(hi)
    lo = DEFAULTS.suspicion_bounds(a.team())[0]
    assert (TeamEvent.FAILED, target) not in a.tick(0.1 + lo + 0.05).events  # not at the floor
    a.on_heartbeat(Heartbeat(target, inc, 0, beat=1), 0.1 + lo + 0.1)  # its refutation
    assert target in a.members
    assert a.table.suspected == {}
    # A member that found it silent itself (and says so) does confirm.
    b = robot()
    [(target, _)] = b.tick(0.0).sends
    b.timeout(0.05)
    b.tick(0.1)
    mine = Heard(target, b.members[target].incarnation, 0, 0, True, others[1])
    b.on_heartbeat(Heartbeat(others[1], 1, 0, heard=[mine]), 0.12)
    assert b.members[target].suspicion.confirmations == 1  # type: ignore[union-attr]


def test_a_suspicion_starting_is_an_event_once() -> None:
    # Auctions stop waiting for a suspect on this event (it is a member still).
    a = robot()
    assert a.unreachable("c", 0.0).events == [(TeamEvent.SUSPECTED, "c")]
    assert a.unreachable("c", 0.01).events == []  # suspected already
    # a teammate's news of a suspicion we did not hold yet
    inc = a.members["d"].incarnation
    news = Heard("d", inc, 0, 0, True, "b")
    step = a.on_heartbeat(Heartbeat("b", 1, 0, heard=[news]), 0.02)
    assert (TeamEvent.SUSPECTED, "d") in step.events
    step = a.on_heartbeat(Heartbeat("e", 1, 0, heard=[news]), 0.03)  # another suspector
    assert (TeamEvent.SUSPECTED, "d") not in step.events
    # our own probe that went unanswered
    b = robot()
    [(target, _)] = b.tick(0.0).sends
    b.timeout(0.05)
    assert (TeamEvent.SUSPECTED, target) in b.tick(0.1).events


def test_an_unreachable_member_is_suspected_at_once_and_can_refute() -> None:
    a = robot()
    a.unreachable("ghost", 0.0)  # not a member: nothing
    assert a.table.suspected == {}
    a.unreachable("c", 0.0)
    assert a.members["c"].suspicion is not None  # not waiting for its turn to be probed
    assert a.members["c"].suspicion.by == ["a"]  # type: ignore[union-attr]
    a.on_heartbeat(Heartbeat("c", 1, 0, beat=5), 0.05)  # its own newer beat refutes
    assert a.members["c"].suspicion is None
    a.unreachable("d", 0.0)
    t = 0.0
    while "d" in a.members and t < 60:
        t += 0.1
        a.tick(t)
    assert "d" not in a.members  # silent: failed when its timer ran out
    assert t <= DEFAULTS.suspicion_bounds(5)[1] + 0.2


def test_probe_requests_are_bounded_and_only_for_members() -> None:
    a = robot(team=("b", "c"))
    assert a.on_probe_request("stranger", ProbeRequest("b", 1), 0.0).sends == []
    assert a.on_probe_request("c", ProbeRequest("ghost", 1), 0.0).sends == []
    steps = [a.on_probe_request("c", ProbeRequest("b", i), 0.0).sends for i in range(500)]
    pings = [msg for sends in steps for to, msg in sends if to == "b"]
    assert len(pings) == MAX_RELAYS
    nacks = [msg for sends in steps for to, msg in sends if to == "c"]
    assert len(nacks) == MAX_RELAYS  # "I am trying", only for the requests taken on
    assert all(isinstance(m, Vouch) and not m.answered for m in nacks)


def test_news_of_invented_robots_is_bounded_and_makes_nobody_a_member() -> None:
    a = robot(team=("b",))
    ghosts = [Heard(f"ghost{i}", 1, 1) for i in range(1000)]
    step = a.on_heartbeat(Heartbeat("b", 1, 0, heard=ghosts), 0.0)
    assert len(step.unknown) == 4 * DEFAULTS.news  # more than anybody sends: ignored
    assert set(a.members) == {"b"}
    susp = [Heard(f"ghost{i}", 1, 1, 0, True, "b") for i in range(30)]
    a.on_heartbeat(Heartbeat("b", 1, 0, heard=susp), 0.0)
    assert a.table.suspected == {}


def team(n: int, *, seed: int = 1, loss: float = 0.01) -> SwimNet:
    return SwimNet([f"r{i:02d}" for i in range(n)], DEFAULTS, seed=seed, loss=loss)


def detection(net: SwimNet, victim: str, at: float) -> float:
    """When the last living robot declared ``victim`` failed, after ``at``."""
    seen = {e.observer: e.at for e in net.failures() if e.robot == victim and e.at >= at}
    assert set(seen) == set(net.living()), "not every living robot declared it failed"
    return max(seen.values()) - at


@pytest.mark.parametrize("n", [10, 60])
def test_a_dead_robot_is_declared_failed_by_all_within_the_bound_and_nobody_else(n: int) -> None:
    net = team(n)
    net.run_until(60.0)
    assert net.failures() == []  # 1 % loss, the defaults: no false failure
    net.kill("r03")
    net.run_until(60.0 + 2 * DEFAULTS.detection_bound_s(n))
    assert detection(net, "r03", 60.0) <= DEFAULTS.detection_bound_s(n)
    assert {e.robot for e in net.failures()} == {"r03"}


def test_an_indirect_probe_saves_a_robot_behind_a_lossy_link() -> None:
    net = team(8, loss=0.0)
    net.lossy("r00", "r01", 1.0)  # r00 and r01 cannot hear each other at all
    net.run_until(300.0)
    assert net.failures() == []
    vouches = net.robots["r00"].counted["ProbeRequest"]
    assert vouches > 0  # they did need others to vouch


def test_a_liar_cannot_kill_a_live_robot() -> None:
    net = team(20)
    victim = net.robots["r01"].swim

    def lie(sender: str, to: str, msg: object) -> bool:
        if sender == "r00" and to != "r01" and isinstance(msg, Heartbeat):
            # Every message of the liar suspects r01 at its latest beat, in others' names.
            doubt = [
                Heard("r01", victim.incarnation, victim.beat, 0, True, f"r{i:02d}")
                for i in range(2, 6)
            ]
            net.transmit(sender, to, msgspec.structs.replace(msg, heard=doubt))
            return True
        return False

    net.intercept = lie
    net.run_until(120.0)
    assert [e for e in net.failures() if e.robot == "r01"] == []
    assert victim.refuted > 0


def test_a_liar_cannot_keep_a_dead_robot_alive_past_the_bound() -> None:
    net = team(20)
    net.run_until(10.0)
    dead = net.robots["r01"].swim
    beats = iter(range(10**6))

    def lie(sender: str, to: str, msg: object) -> bool:
        if sender == "r00" and isinstance(msg, Heartbeat):
            alive = [Heard("r01", dead.incarnation, 100 + next(beats))]
            net.transmit(sender, to, msgspec.structs.replace(msg, heard=alive))
            return True
        return False

    net.intercept = lie
    net.kill("r01")
    bound = DEFAULTS.hearsay_window_s(20) + DEFAULTS.detection_bound_s(20)
    net.run_until(10.0 + 2 * bound)
    assert detection(net, "r01", 10.0) <= bound


@settings(max_examples=15, deadline=None)
@given(st.integers(3, 16), st.integers(0, 2**16), st.floats(0.0, 0.05))
@example(16, 16, 0.05)  # a suspicion's echoes brought it to the floor: a false failure
def test_any_team_under_loss_keeps_its_members_and_finds_its_dead(
    n: int, seed: int, loss: float
) -> None:
    net = team(n, seed=seed, loss=loss)
    net.run_until(30.0)
    assert net.failures() == []
    net.kill("r00")
    bound = DEFAULTS.detection_bound_s(n)
    net.run_until(30.0 + 2 * bound)
    assert detection(net, "r00", 30.0) <= bound
    assert {e.robot for e in net.failures()} == {"r00"}


def test_the_same_seed_gives_the_same_run() -> None:
    runs = []
    for _ in range(2):
        net = team(12, seed=5, loss=0.05)
        net.run_until(20.0)
        net.kill("r02")
        net.run_until(40.0)
        runs.append([(e.at, e.observer, e.event) for e in net.events])
    assert runs[0] == runs[1]
    assert any(event is TeamEvent.FAILED for _, _, event in runs[0])


def test_a_newcomer_that_answered_our_probe_and_left_before_it_concluded() -> None:
    # sim-test (seed in 0-299 on a loaded run): the probe's answer came, then the goodbye;
    # concluding it must not look the newcomer up as a member any more.
    a = Swim("a", 1, DEFAULTS, random.Random(0))
    a.on_heartbeat(Heartbeat("j1", 1, 0), 0.0)  # joined; its nonce never answered
    # the newcomer's nonce again, then the round robin's probe (number 1)
    (target, probe) = a.tick(0.1).sends[-1]
    assert target == "j1"
    assert isinstance(probe, Heartbeat)
    assert probe.probe == 1
    a.on_heartbeat(Heartbeat("j1", 1, 0, ack=probe.probe), 0.12)
    assert a.on_goodbye("j1", 1).events == [(TeamEvent.LEFT, "j1")]
    step = a.tick(0.2)
    assert "j1" not in a.members
    assert step.confirmed == []
