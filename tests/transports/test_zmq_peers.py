"""Which peers a ZeroMQ transport keeps dialling, decided on explicit time (no sockets)."""

from __future__ import annotations

from btcap.transports.zmq_peers import UNREACHABLE_TRIES, Fate, PeerBook


def book(max_strangers: int = 4, max_forgotten: int = 3) -> PeerBook:
    return PeerBook(30.0, max_strangers, max_forgotten)


def test_a_stranger_that_speaks_is_kept_and_one_that_does_not_is_dropped() -> None:
    b = book()
    b.met("a", 0.0)
    b.met("b", 1.0)
    b.vouched("a")
    assert b.expired("a", 0.0) is Fate.KEEP
    assert b.expired("b", 1.0) is Fate.DROP
    assert b.expired("b", 0.5) is Fate.KEEP  # a timer of an earlier life


def test_strangers_are_bounded_and_the_oldest_makes_room() -> None:
    b = book(max_strangers=3)
    for n, peer in enumerate("xyz"):
        b.met(peer, float(n))
    assert b.full()
    assert b.oldest() == "x"
    b.dropped("x")
    assert not b.full()


def test_a_stranger_nobody_answers_for_is_dropped_after_a_few_dials() -> None:
    b = book()
    b.met("ghost", 0.0)
    fates = [b.unreachable("ghost") for _ in range(UNREACHABLE_TRIES)]
    assert fates == [Fate.KEEP] * (UNREACHABLE_TRIES - 1) + [Fate.DROP]


def test_a_peer_that_spoke_and_fell_silent_is_watched_then_forgotten() -> None:
    b = book()
    # Its link dropped (or nobody answers any more): a stranger again, given its time.
    assert b.lapsed("r1") is Fate.WATCH
    b.met("r1", 5.0)
    assert b.lapsed("r1") is Fate.KEEP  # already watched
    assert all(b.unreachable("r1") is Fate.KEEP for _ in range(10))
    assert b.expired("r1", 5.0) is Fate.FORGET  # dialled back if it speaks again
    assert b.unreachable("r2") is Fate.WATCH  # a vouched peer nobody answers for


def test_forgotten_endpoints_are_recalled_once_and_bounded() -> None:
    b = book(max_forgotten=2)
    b.remember("a", "tcp://a")
    b.remember("b", "tcp://b")
    b.remember("c", "tcp://c")
    assert b.recall("a") is None  # the oldest went
    assert b.recall("b") == "tcp://b"
    assert b.recall("b") is None
    b.dropped("c")  # dropping its sockets does not forget where it was
    assert b.recall("c") == "tcp://c"
