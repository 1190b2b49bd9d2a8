"""Heartbeat gossip decided on explicit inputs: turns, introductions, hearsay."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import given
from hypothesis import strategies as st

from btcap.team.core.gossip import Beat, BeatPlan, Introductions, Turns, detection_periods
from btcap.team.core.members import MemberTable, TeamEvent


@given(st.integers(2, 60), st.integers(1, 10), st.integers(0, 2**32))
def test_every_peer_gets_a_turn_within_ceil_peers_over_fanout_rounds(
    peers: int, fanout: int, seed: int
) -> None:
    names = [f"r{i}" for i in range(peers)]
    turns = Turns(random.Random(seed))
    rounds = math.ceil(peers / fanout)
    for _ in range(3):  # not just the first cycle
        seen: set[str] = set()
        for _ in range(rounds):
            taken = turns.take(names, fanout)
            assert len(taken) == min(fanout, peers) == len(set(taken))
            seen.update(taken)
        if peers % fanout == 0:  # whole rounds: each cycle is a permutation
            assert seen == set(names)
    # Within two cycles' worth of rounds, nobody is ever skipped.
    last: dict[str, int] = {}
    for r in range(4 * rounds):
        for name in turns.take(names, fanout):
            last[name] = r
    assert set(last) == set(names)


def test_turns_follow_a_changing_team_and_are_reproducible() -> None:
    a, b = Turns(random.Random("x")), Turns(random.Random("x"))
    team = {f"r{i}" for i in range(10)}
    assert [a.take(team, 3) for _ in range(5)] == [b.take(team, 3) for _ in range(5)]
    team -= {"r1", "r2", "r3"}
    for _ in range(10):
        assert set(a.take(team, 3)) <= team  # gone robots are never picked
    assert a.take({"r1", "r2"}, 3) == ["r1", "r2"]  # a small team: everybody


def test_introductions_are_rate_limited_and_bounded() -> None:
    intro = Introductions(interval_s=1.0, limit=3)
    assert intro.due(["a", "b"], 0.0) == ["a", "b"]
    assert intro.due(["a", "b", "c"], 0.5) == ["c"]
    assert intro.due(["a"], 1.0) == ["a"]  # asked again after the interval
    assert intro.due([f"ghost{i}" for i in range(100)], 1.1) == [f"ghost{i}" for i in range(100)]
    assert len(intro) == 3


def test_hearsay_keeps_a_member_alive_but_never_makes_or_changes_one() -> None:
    t = MemberTable("me", failure_timeout_s=1.0)
    assert t.hearsay("b", 1, 5, 0.0) is True  # unknown: worth an introduction
    assert "b" not in t.members
    assert t.heartbeat("b", 1, 0, 0.0, beat=5) == [TeamEvent.JOINED]
    assert t.hearsay("b", 1, 5, 0.9) is False  # not newer: no refresh
    assert t.expire(1.05) == ["b"]
    assert t.heartbeat("b", 1, 0, 2.0, beat=6) == [TeamEvent.JOINED]
    assert t.hearsay("b", 1, 7, 2.9) is False  # newer: alive until 3.9
    assert t.hearsay("b", 2, 99, 3.5) is False  # another life: only b itself says so
    assert t.expire(3.8) == []
    assert t.members["b"].incarnation == 1
    assert t.expire(3.95) == ["b"]
    assert t.hearsay("me", 1, 1, 4.0) is False


@pytest.mark.parametrize(("team", "fanout", "periods"), [(5, 8, 3), (9, 8, 3), (50, 8, 6)])
def test_detection_periods(team: int, fanout: int, periods: int) -> None:
    assert detection_periods(team, fanout) == periods


def test_an_old_beat_heard_late_keeps_a_member_alive_only_from_when_it_was_heard() -> None:
    t = MemberTable("me", failure_timeout_s=1.0)
    t.heartbeat("b", 1, 0, 0.0, beat=1)
    t.hearsay("b", 1, 2, now=0.9, age_s=0.8)  # beat 2 was heard at 0.1, not at 0.9
    assert t.expire(1.15) == ["b"]
    t.heartbeat("b", 1, 0, 2.0, beat=3)
    t.hearsay("b", 1, 4, now=2.5, age_s=-5.0)  # a clock that runs ahead: no later than now
    assert t.expire(3.45) == []
    assert t.expire(3.55) == ["b"]


def test_members_are_beaten_to_first_however_many_strangers_the_transport_holds() -> None:
    plan = BeatPlan(8, random.Random(1))
    ghosts = {f"ghost-{i}" for i in range(32)}
    for _ in range(20):  # a two-robot team whose peer table an attacker filled
        beat = plan.next({"origin"}, {"origin"} | ghosts)
        assert not beat.everyone
        assert "origin" in beat.to
        assert len(beat.to) == 9
        assert not beat.heard  # one member, beaten directly every period
    assert plan.next({"a", "b"}, {"a", "b", "c"}) == Beat(everyone=True)


def test_past_the_fanout_members_take_turns_and_carry_hearsay() -> None:
    plan = BeatPlan(3, random.Random(2))
    team = {f"r{i}" for i in range(12)}
    seen: set[str] = set()
    for _ in range(4):
        beat = plan.next(team, team | {"seed"})
        assert beat.heard
        assert "seed" in beat.to  # the one non-member gets a beat every period
        seen |= set(beat.to) - {"seed"}
    assert seen == team


def test_a_teammate_lying_about_a_dead_robot_keeps_it_alive_only_so_long() -> None:
    t = MemberTable("me", failure_timeout_s=1.0)
    t.heartbeat("b", 1, 0, 0.0, beat=1)  # b's last own heartbeat
    beat = 1
    for now in (0.5, 1.0, 1.5, 2.0):  # a liar reports ever newer beats of b
        beat += 1
        t.hearsay("b", 1, beat, now, limit_s=1.5)
    assert t.members["b"].last_seen == 1.5  # the report at 2.0 came too late after 0.0
    assert t.expire(2.6) == ["b"]
