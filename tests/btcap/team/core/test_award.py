"""The award step of every strategy, on explicit bids and answers (no actors, no I/O)."""

from __future__ import annotations

import pytest

from btcap.team.core.auction import REASON_CHARS, Auction, AuctionOutcome
from btcap.team.core.award import AwardRound, bounded, passed_over
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award, Bid, CancelExecution, NoBid

A1 = AuctionId("o", 1)
RUN = ExecutionId("o", "tree/move", 7)
TASK = AssignmentTask(RUN, "Move", "move", {"to": 3}, frozenset("abc"), 2.0, paused=True)


def bid(robot: str, cost: float) -> Bid:
    return Bid(A1, robot, cost, f"impl-{robot}")


def test_the_bidders_are_asked_in_turn_until_one_accepts() -> None:
    award = AwardRound(A1, TASK, [bid("a", 1), bid("b", 2), bid("c", 3)])
    first = award.next()
    assert first == Award(A1, RUN, "Move", "impl-a", {"to": 3}, 2.0, paused=True)
    assert award.offered.robot == "a"
    assert award.declined("busy") == "declined the award: busy"
    second = award.next()
    assert second is not None
    assert second.implementation == "impl-b"
    assert award.unanswered("no reply") == CancelExecution(RUN, "award withdrawn")
    assert award.next() is not None
    assert award.offered.robot == "c"
    assert award.accepted() == Assigned("c", "impl-c", 3)
    assert award.reasons == {
        "a": "declined the award: busy",
        "b": "no answer to the award (no reply)",
    }


def test_a_suspects_bid_is_asked_last() -> None:
    """The cheapest bidder ``a`` is suspected of failure when the award is made: ``b`` is
    asked first (nobody waits the award timeout on a robot likely gone), ``a`` only if
    every other bidder declined."""
    award = AwardRound(A1, TASK, [bid("a", 1), bid("b", 2), bid("c", 3)])
    award.defer({"a", "x"})
    asked = []
    while award.next() is not None:
        asked.append(award.offered.robot)
        award.declined("busy")
    assert asked == ["b", "c", "a"]


def test_when_everyone_declines_the_result_says_why_robot_by_robot() -> None:
    passed = {"d": "no answer"}
    award = AwardRound(A1, TASK, [bid("a", 1)], passed)
    assert award.next() is not None
    award.declined("battery low")
    assert award.next() is None
    assert award.result() == Unassigned({"d": "no answer", "a": "declined the award: battery low"})
    assert award.reasons is passed  # filled in place: the caller reports it


def test_a_peers_over_long_decline_reason_is_bounded() -> None:
    award = AwardRound(A1, TASK, [bid("a", 1)])
    award.next()
    kept = award.declined("x" * 1000)
    assert kept == "declined the award: " + "x" * REASON_CHARS
    assert award.reasons["a"] == kept
    assert bounded("y" * 1000) == "y" * REASON_CHARS
    assert bounded("ok") == "ok"


def test_a_cancelled_ask_is_withdrawn_without_a_reason() -> None:
    award = AwardRound(A1, TASK, [bid("a", 1)])
    with pytest.raises(RuntimeError, match="next"):
        award.offered  # noqa: B018 (nothing asked yet)
    award.next()
    assert award.withdrawal() == CancelExecution(RUN, "award withdrawn")
    assert award.reasons == {}


def test_no_bid_no_award() -> None:
    award = AwardRound(A1, TASK, [])
    assert award.next() is None
    assert award.result() == Unassigned({})


def test_passed_over_names_declines_silence_the_reserve_and_taken_robots() -> None:
    auction = Auction(A1, "Move", frozenset("abcde"), deadline=5.0)
    auction.offer(bid("a", 1.0))
    auction.offer(bid("b", 2.0))
    auction.offer(bid("c", 4.0))
    auction.offer(NoBid(A1, "d", "z" * 500))
    assert not auction.closed(4.9)
    assert auction.closed(5.0)
    outcome = auction.outcome()
    assert passed_over(outcome, 3.0, {"a"}) == {
        "d": "z" * REASON_CHARS,
        "e": "no answer",
        "a": "took another task of the same round",
        "c": "bid 4 not below 3",
    }
    assert passed_over(AuctionOutcome([bid("a", 1)], {}, frozenset()), None, ()) == {}
