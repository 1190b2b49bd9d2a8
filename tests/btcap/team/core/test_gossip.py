"""Gossip decided on explicit inputs: turns, probe order, news, introductions."""

from __future__ import annotations

import math
import random

from hypothesis import given
from hypothesis import strategies as st

from btcap.team.core.gossip import Introductions, ProbeOrder, Rumours, Turns
from btcap.team.messages import Heard


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


def test_probes_visit_every_member_once_a_round_in_a_shuffled_order() -> None:
    order = ProbeOrder(random.Random(3))
    members = {f"r{i}": None for i in range(7)}
    rounds = [[order.next(members) for _ in range(7)] for _ in range(3)]
    for r in rounds:
        assert sorted(r) == sorted(members)  # type: ignore[type-var]
    assert rounds[0] != rounds[1]  # reshuffled
    del members["r3"]
    assert all(order.next(members) != "r3" for _ in range(14))  # gone: never probed
    assert order.next({}) is None


@given(st.integers(1, 40), st.integers(0, 2**32))
def test_every_member_is_probed_within_two_rounds(n: int, seed: int) -> None:
    order = ProbeOrder(random.Random(seed))
    members = {f"r{i}": None for i in range(n)}
    last: dict[str, int] = {}
    for p in range(6 * n):
        name = order.next(members)
        assert name is not None
        assert p - last.get(name, -1) <= 2 * n  # never skipped past two rounds
        last[name] = p


def test_news_is_sent_a_bounded_number_of_times_least_sent_first() -> None:
    news = Rumours(limit=3)
    news.add(Heard("a", 1, 1))
    news.add(Heard("b", 1, 1))
    assert news.take(1, times=2) == [Heard("a", 1, 1)]
    assert news.take(1, times=2) == [Heard("b", 1, 1)]  # the least sent first
    assert news.take(5, times=2, first="b") == [Heard("b", 1, 1), Heard("a", 1, 1)]
    assert news.take(5, times=2) == []  # each sent twice: forgotten
    news.add(Heard("c", 1, 1))
    news.add(Heard("c", 1, 2, 0, True, "a"))  # newer news of c replaces the older
    assert news.take(5, times=2) == [Heard("c", 1, 2, 0, True, "a")]
    for i in range(10):  # a flood of news is bounded
        news.add(Heard(f"ghost{i}", 1, 1))
    assert len(news) == 3
