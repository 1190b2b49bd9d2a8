"""Bounds on what a member may make a robot do in its own name, on explicit time: awards
only for bids made (or tasks claimed), once, from the auctioneer; budgets per peer."""

from __future__ import annotations

import pytest

from btcap.team.core.body import Body
from btcap.team.core.bounds import BidBook, Budgets, bid_memory_s
from btcap.team.core.hosting import HostLeases
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award

A1 = AuctionId("a", 1)
E1 = ExecutionId("a", "root/count", 1)


def award(
    auction: AuctionId = A1, execution: ExecutionId = E1, interface: str = "Count", lease: float = 1
) -> Award:
    return Award(auction, execution, interface, "impl", {}, lease)


def test_an_award_nobody_bid_for_is_refused() -> None:
    book = BidBook(10.0)
    assert "we made no bid in auction a#1" in str(book.refuse("a", award(), 0.0))


def test_an_award_for_a_bid_made_is_taken_once() -> None:
    book = BidBook(10.0)
    book.bid(A1, "Count", 0.0)
    assert book.refuse("a", award(), 5.0) is None
    book.taken(award())
    # The same auction cannot award this robot a second execution.
    again = award(execution=ExecutionId("a", "root/count", 2))
    assert "no bid" in str(book.refuse("a", again, 5.0))


def test_only_the_auctioneer_awards_and_only_what_was_bid_for() -> None:
    book = BidBook(10.0)
    book.bid(A1, "Count", 0.0)
    assert "only auctioneer a" in str(book.refuse("mallory", award(), 1.0))
    assert "we bid for Count, not Explore" in str(book.refuse("a", award(interface="Explore"), 1))
    other = AuctionId("mallory", 1)  # a number we bid under, minted by another auctioneer
    assert "no bid" in str(book.refuse("mallory", award(auction=other), 1.0))


def test_a_bid_is_forgotten_after_its_time() -> None:
    book = BidBook(10.0)
    book.bid(A1, "Count", 0.0)
    assert book.refuse("a", award(), 10.0) is None
    assert "no bid" in str(book.refuse("a", award(), 10.5))
    book.bid(AuctionId("a", 2), "Count", 11.0)  # trims what expired
    assert len(book) == 1


def test_a_consensus_claim_lets_its_origin_award_it() -> None:
    book = BidBook(10.0)
    book.claimed(E1, 0.0)
    # Consensus awards are filed under the origin's own auction numbers.
    assert book.refuse("a", award(auction=AuctionId("a", 77)), 1.0) is None
    forged = award(auction=AuctionId("mallory", 1))
    assert "no bid" in str(book.refuse("mallory", forged, 1.0))
    book.taken(award(auction=AuctionId("a", 77)))
    assert "no bid" in str(book.refuse("a", award(auction=AuctionId("a", 77)), 1.0))


def test_the_book_is_bounded() -> None:
    book = BidBook(1e9, max_entries=100)
    for n in range(1000):
        book.bid(AuctionId("a", n), "Count", float(n))
        book.claimed(ExecutionId("a", "x", n), float(n))
    assert len(book) == 200
    assert book.refuse("a", award(auction=AuctionId("a", 999)), 1000.0) is None
    assert "no bid" in str(book.refuse("a", award(auction=AuctionId("a", 0)), 1000.0))


def test_bids_outlive_their_auction_and_its_award() -> None:
    assert bid_memory_s(1.0, 0.5) == 15.0


def test_a_lease_over_the_maximum_is_refused_naming_the_setting() -> None:
    host: HostLeases[str] = HostLeases("b", Body(), max_lease_s=300.0)
    why = host.refuse_award("a", award(lease=1e6))
    assert why is not None
    assert "lease_s 1e+06 is over this robot's max_lease_s 300" in why
    assert host.refuse_award("a", award(lease=300.0)) is None


def test_a_budget_allows_a_burst_then_its_rate() -> None:
    b = Budgets(rate=2.0, burst=3.0)
    assert [b.allow("p", 0.0) for _ in range(4)] == [True, True, True, False]
    assert b.allow("p", 0.25) is False  # half a token back
    assert b.allow("p", 0.5) is True  # one whole
    assert b.refused == 2
    # Another peer is not slowed down by the first.
    assert all(b.allow("q", 0.5) for _ in range(3))
    # Refilled to the burst, never beyond.
    assert sum(b.allow("p", 100.0) for _ in range(10)) == 3


def test_budgets_keep_a_bounded_table_of_peers() -> None:
    b = Budgets(rate=1.0, burst=1.0, max_peers=10)
    for n in range(1000):
        b.allow(f"ghost-{n}", 0.0)
    assert len(b) == 10
    b.forget("ghost-999")
    assert len(b) == 9


@pytest.mark.parametrize(("rate", "burst"), [(0.0, 1.0), (float("inf"), 1.0), (1.0, 0.5)])
def test_a_budget_needs_a_rate_and_a_burst(rate: float, burst: float) -> None:
    with pytest.raises(ValueError, match="budget"):
        Budgets(rate, burst)
