"""Membership decisions on explicit time: joins, failures, restarts, goodbyes, bounds."""

from __future__ import annotations

from btcap.team.core.members import MemberTable, TeamEvent


def test_join_failure_and_a_late_heartbeat_rejoins() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    assert t.heartbeat("b", 1, 0, now=0.0) == [TeamEvent.JOINED]
    assert t.heartbeat("b", 1, 0, now=0.4) == []
    assert t.expire(0.89) == []
    assert t.expire(0.91) == ["b"]
    assert t.alive() == {"a"}
    # b was declared dead but was only slow: it joins again, as a new member.
    assert t.heartbeat("b", 1, 0, now=1.0) == [TeamEvent.JOINED]
    assert t.alive() == {"a", "b"}


def test_an_old_heartbeat_delivered_late_does_not_move_time_back() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 1, 0, now=1.0)
    t.heartbeat("b", 1, 0, now=0.2)
    assert t.expire(1.4) == []


def test_a_restart_is_a_failure_and_a_join() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 1, 0, now=0.0)
    assert t.heartbeat("b", 2, 0, now=0.1) == [TeamEvent.FAILED, TeamEvent.JOINED]


def test_a_new_repository_version_is_a_change() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 1, 0, now=0.0)
    assert t.heartbeat("b", 1, 3, now=0.1) == [TeamEvent.CHANGED]


def test_goodbye_of_another_incarnation_changes_nothing() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 2, 0, now=0.0)
    assert t.goodbye("b", 1) is False
    assert t.goodbye("b", 2) is True
    assert t.goodbye("b", 2) is False


def test_own_heartbeats_are_ignored_and_the_table_is_bounded() -> None:
    t = MemberTable("a", failure_timeout_s=0.5, max_members=3)
    assert t.heartbeat("a", 1, 0, now=0.0) == []
    for i in range(10):
        t.heartbeat(f"r{i}", 1, 0, now=0.0)
    assert len(t.members) == 3
    t.expire(1.0)
    assert t.heartbeat("real", 1, 0, now=1.0) == [TeamEvent.JOINED]


def test_a_late_heartbeat_of_an_older_incarnation_changes_nothing() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 100, 0, now=0.0)
    assert t.heartbeat("b", 200, 0, now=0.1) == [TeamEvent.FAILED, TeamEvent.JOINED]
    assert t.heartbeat("b", 100, 0, now=0.15) == []  # from before the restart, delivered late
    assert t.heartbeat("b", 200, 0, now=0.2) == []
    assert t.members["b"].incarnation == 200


def test_a_member_coming_free_is_news() -> None:
    t = MemberTable("a", failure_timeout_s=0.5)
    t.heartbeat("b", 1, 0, now=0.0, busy=True)
    assert t.heartbeat("b", 1, 0, now=0.1, busy=True) == []
    assert t.heartbeat("b", 1, 0, now=0.2, busy=False) == [TeamEvent.FREED]
    assert t.heartbeat("b", 1, 0, now=0.3, busy=False) == []
    assert t.heartbeat("b", 1, 0, now=0.4, busy=True) == []  # taken again: no news
