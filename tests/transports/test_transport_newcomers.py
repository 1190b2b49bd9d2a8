"""The book of inbound connections without a hello (transports/newcomers.py), on explicit
time: which to close, when, and which to keep."""

from __future__ import annotations

import pytest

from btcap.transports.newcomers import LINKS_PER_PEER, Newcomers


def test_a_silent_connection_is_closed_at_its_deadline_not_before() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    assert book.accepted(5, "k5", now=0.0) == []
    assert book.next_due() == 10.0
    assert book.due(9.999) == []
    assert book.due(10.0) == [(5, "k5")]
    assert book.next_due() is None
    assert book.closed == 1


def test_a_stall_does_not_count_against_newcomers() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    book.accepted(5, "k5", now=0.0)
    book.accepted(6, "k6", now=4.0)
    book.stalled(7.5)  # the caller read nothing for 7.5 s
    assert book.due(17.0) == []
    assert book.next_due() == 17.5
    assert book.due(17.5) == [(5, "k5")]
    book.stalled(0.0)
    assert book.due(21.4) == []
    assert book.due(21.5) == [(6, "k6")]


def test_a_hello_in_time_keeps_the_connection() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    book.accepted(5, "k5", now=0.0)
    assert book.spoke(5, "r1", "ignored") == []
    assert book.due(100.0) == []
    assert book.peer_of(5) == "r1"
    assert book.links[5] == ("r1", "k5")  # the key seen at the accept


def test_beyond_the_cap_the_oldest_make_room() -> None:
    book = Newcomers(deadline=10.0, cap=3)
    for fd in range(3):
        assert book.accepted(fd, f"k{fd}", now=float(fd)) == []
    assert book.accepted(3, "k3", now=3.0) == [(0, "k0")]
    assert list(book.waiting) == [1, 2, 3]
    assert book.next_due() == 11.0


def test_a_closed_connection_is_forgotten() -> None:
    book = Newcomers(deadline=10.0, cap=3)
    book.accepted(5, "k5", now=0.0)
    book.gone(5)
    assert book.due(100.0) == []
    book.accepted(6, "k6", now=0.0)
    book.spoke(6, "r1", "k6")
    book.gone(6)
    assert book.peer_of(6) is None
    assert not book.linked("r1")


def test_a_hello_read_before_its_accept_event_is_not_undone_by_it() -> None:
    """The ROUTER's messages and its monitor's events are read by separate callbacks."""
    book = Newcomers(deadline=10.0, cap=3)
    book.spoke(7, "r1", "k7")
    assert book.accepted(7, "k7", now=0.0) == []
    assert book.due(100.0) == []


def test_a_dropped_peers_links_must_say_hello_again() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    book.accepted(5, "k5", now=0.0)
    book.spoke(5, "ghost", "k5")
    assert book.dropped("ghost", now=50.0) == []
    assert book.due(59.0) == []
    assert book.due(60.0) == [(5, "k5")]


def test_a_dropped_peer_that_speaks_again_keeps_its_link() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    book.spoke(5, "r1", "k5")
    book.dropped("r1", now=50.0)
    book.spoke(5, "r1", "k5")  # dialled back on its next message
    assert book.due(100.0) == []


def test_a_name_claimed_over_and_over_keeps_a_few_links() -> None:
    book = Newcomers(deadline=10.0, cap=100)
    closed = []
    for fd in range(10):
        book.accepted(fd, f"k{fd}", now=0.0)
        closed += book.spoke(fd, "r1", f"k{fd}")
    kept = 10 - LINKS_PER_PEER
    assert closed == [(fd, f"k{fd}") for fd in range(kept)]
    assert [fd for fd in book.links] == list(range(kept, 10))


def test_the_links_kept_per_peer_are_an_option() -> None:
    book = Newcomers(deadline=10.0, cap=100, links=2)
    closed = []
    for fd in range(5):
        book.accepted(fd, f"k{fd}", now=0.0)
        closed += book.spoke(fd, "r1", f"k{fd}")
    assert [fd for fd, _ in closed] == [0, 1, 2]
    assert list(book.links) == [3, 4]
    with pytest.raises(ValueError, match="links 0"):
        Newcomers(deadline=10.0, cap=100, links=0)


def test_a_link_named_again_by_another_peer_moves() -> None:
    book = Newcomers(deadline=10.0, cap=8)
    book.spoke(5, "a", "k5")
    book.spoke(5, "b", "k5")
    assert not book.linked("a")
    assert book.peer_of(5) == "b"


@pytest.mark.parametrize(("deadline", "cap"), [(0.0, 1), (1.0, 0)])
def test_limits_must_be_positive(deadline: float, cap: int) -> None:
    with pytest.raises(ValueError, match="must be > 0"):
        Newcomers(deadline, cap)
