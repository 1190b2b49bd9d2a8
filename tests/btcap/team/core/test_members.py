"""Membership decisions on explicit time: joins, suspicions, failures, restarts, goodbyes,
bounds."""

from __future__ import annotations

from btcap.team.core.members import Hearsay, MemberTable, Suspicion, TeamEvent


def half(_s: Suspicion) -> float:
    return 0.5


def test_join_suspicion_failure_and_a_late_heartbeat_rejoins() -> None:
    t = MemberTable("a")
    assert t.heartbeat("b", 1, 0, now=0.0) == [TeamEvent.JOINED]
    assert t.heartbeat("b", 1, 0, now=0.4) == []
    assert t.expire(10.0, half) == []  # silence alone fails nobody: only a suspicion
    assert t.suspect("b", 1, 0, "a", now=0.5)
    assert t.expire(0.99, half) == []
    assert t.expire(1.0, half) == ["b"]
    assert t.alive() == {"a"}
    # b was declared dead but was only slow: it joins again, as a new member.
    assert t.heartbeat("b", 1, 0, now=1.1) == [TeamEvent.JOINED]
    assert t.alive() == {"a", "b"}


def test_its_own_word_ends_a_suspicion_and_so_does_a_newer_beat_passed_on() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 1, 0, now=0.0, beat=3)
    assert t.suspect("b", 1, 3, "c", now=0.1)
    t.heartbeat("b", 1, 0, now=0.2, beat=3)  # b itself: alive
    assert t.expire(5.0, half) == []
    assert t.suspect("b", 1, 3, "c", now=5.0)  # the same doubt again
    assert t.hearsay("b", 1, 3, 5.1, window_s=10) is Hearsay.NOTHING  # not newer
    assert t.hearsay("b", 1, 4, 5.1, window_s=10) is Hearsay.NEWS  # refuted
    assert t.expire(6.0, half) == []
    assert not t.suspect("b", 1, 3, "c", now=6.0)  # older than what we know: stale


def test_confirmations_count_distinct_suspectors() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 1, 0, now=0.0)
    assert t.suspect("b", 1, 0, "c", 0.1)
    assert not t.suspect("b", 1, 0, "c", 0.2)  # the same suspector again
    assert t.suspect("b", 1, 0, "d", 0.2)
    s = t.members["b"].suspicion
    assert s is not None
    assert (s.since, s.confirmations) == (0.1, 1)
    assert t.suspect("b", 1, 2, "e", 0.3)  # a newer beat: a new suspicion
    s = t.members["b"].suspicion
    assert s is not None
    assert (s.since, s.beat, s.confirmations) == (0.3, 2, 0)


def test_a_teammate_lying_about_a_dead_robot_keeps_it_alive_only_so_long() -> None:
    t = MemberTable("me")
    t.heartbeat("b", 1, 0, 0.0, beat=1)  # b's last own word
    beat = 1
    for now in (0.5, 1.0, 1.5):  # a liar reports ever newer beats of b, within the window
        beat += 1
        t.suspect("b", 1, beat - 1, "c", now)
        assert t.hearsay("b", 1, beat, now, window_s=1.5) is Hearsay.NEWS
    t.suspect("b", 1, beat, "c", 1.6)
    assert t.hearsay("b", 1, beat + 1, 2.0, window_s=1.5) is Hearsay.NOTHING  # too late
    assert t.expire(2.1, half) == ["b"]


def test_hearsay_never_makes_changes_or_ends_a_member() -> None:
    t = MemberTable("me")
    assert t.hearsay("b", 1, 5, 0.0, window_s=1) is Hearsay.UNKNOWN  # worth an introduction
    assert not t.suspect("b", 1, 5, "c", 0.0)
    assert "b" not in t.members
    t.heartbeat("b", 1, 7, 0.0, beat=5)
    assert t.hearsay("b", 2, 99, 0.1, window_s=1) is Hearsay.NOTHING  # another life
    assert not t.suspect("b", 2, 99, "c", 0.1)
    assert t.members["b"].repo_version == 7
    assert t.hearsay("me", 1, 1, 0.2, window_s=1) is Hearsay.NOTHING


def test_a_restart_is_a_failure_and_a_join() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 1, 0, now=0.0)
    t.suspect("b", 1, 0, "c", now=0.05)
    assert t.heartbeat("b", 2, 0, now=0.1) == [TeamEvent.FAILED, TeamEvent.JOINED]
    assert t.suspected == {}


def test_a_new_repository_version_is_a_change_unless_older_than_what_we_hold() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 1, 0, now=0.0)
    assert t.heartbeat("b", 1, 3, now=0.1, beat=2) == [TeamEvent.CHANGED]
    assert t.heartbeat("b", 1, 2, now=0.2, beat=1) == []  # reordered: an older word
    assert t.members["b"].repo_version == 3


def test_goodbye_of_another_incarnation_changes_nothing() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 2, 0, now=0.0)
    assert t.goodbye("b", 1) is False
    assert t.goodbye("b", 2) is True
    assert t.goodbye("b", 2) is False


def test_own_heartbeats_are_ignored_and_the_table_is_bounded() -> None:
    t = MemberTable("a", max_members=3)
    assert t.heartbeat("a", 1, 0, now=0.0) == []
    for i in range(10):
        t.heartbeat(f"r{i}", 1, 0, now=0.0)
    assert len(t.members) == 3
    t.suspect("r0", 1, 0, "a", 0.0)
    t.expire(1.0, half)
    assert t.heartbeat("real", 1, 0, now=1.0) == [TeamEvent.JOINED]


def test_a_late_heartbeat_of_an_older_incarnation_changes_nothing() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 100, 0, now=0.0)
    assert t.heartbeat("b", 200, 0, now=0.1) == [TeamEvent.FAILED, TeamEvent.JOINED]
    assert t.heartbeat("b", 100, 0, now=0.15) == []  # from before the restart, delivered late
    assert t.heartbeat("b", 200, 0, now=0.2) == []
    assert t.members["b"].incarnation == 200


def test_a_member_coming_free_is_news() -> None:
    t = MemberTable("a")
    t.heartbeat("b", 1, 0, now=0.0, busy=True)
    assert t.heartbeat("b", 1, 0, now=0.1, busy=True) == []
    assert t.heartbeat("b", 1, 0, now=0.2, busy=False) == [TeamEvent.FREED]
    assert t.heartbeat("b", 1, 0, now=0.3, busy=False) == []
    assert t.heartbeat("b", 1, 0, now=0.4, busy=True) == []  # taken again: no news
