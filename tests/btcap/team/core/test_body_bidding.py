"""The body and bid evaluation."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pytest

from btcap.bt.leaves import AlwaysSuccess
from btcap.team.allocation.strategies import check_strategy
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.auction import REASON_CHARS, Auction
from btcap.team.core.bidding import bidding_after, evaluate
from btcap.team.core.body import Body
from btcap.team.core.planning import optimal_plan
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Bid, CallForBids, NoBid

A1 = AuctionId("a", 1)
CFB = CallForBids(A1, "Count", "Count()->()", {})


@dataclass
class Impl:
    name: str
    price: float | None
    needs: str | None = None
    broken: bool = False
    #: prices work after what the robot holds from where that leaves it (its own way)
    asks: bool = True
    heard: list[bool] | None = None

    def cost(self, inputs: Mapping[str, Any]) -> float | None:
        if self.broken:
            raise ZeroDivisionError("bid")
        if self.asks:
            after = bidding_after()
            if self.heard is not None:
                self.heard.append(after)
        return self.price


def unmet(impl: Impl) -> str | None:
    return impl.needs


def test_the_cheapest_allowed_implementation_bids_with_the_wait() -> None:
    impls = [Impl("dear", 5.0), Impl("cheap", 1.0, needs="precondition x"), Impl("ok", 2.0)]
    ev = evaluate(CFB, "b", impls, {}, wait=3.0, unmet=unmet)
    assert ev.answer == Bid(A1, "b", 5.0, "ok", 3.0)  # 3 of it the wait


def test_a_bid_function_that_never_asks_gets_the_detour_for_later_work() -> None:
    # Priced from where the busy robot stands (5), the task may cost up to the 20 of held
    # work more: that work may leave the robot as far away as it costs.
    heard: list[bool] = []
    naive = evaluate(CFB, "r", [Impl("a", 5.0, asks=False)], {}, wait=20.0, unmet=unmet)
    assert naive.answer == Bid(A1, "r", 45.0, "a", 20.0)
    aware = evaluate(CFB, "r", [Impl("a", 5.0, heard=heard)], {}, wait=20.0, unmet=unmet)
    assert aware.answer == Bid(A1, "r", 25.0, "a", 20.0)  # its own price, trusted
    assert heard == [True]
    now = evaluate(CFB, "r", [Impl("a", 5.0, asks=False)], {}, wait=0.0, unmet=unmet)
    assert now.answer == Bid(A1, "r", 5.0, "a")  # idle: no held work, no detour
    # the cheapest is chosen on the prices with the detour: a naive 5 is dearer than 20
    both = [Impl("naive", 5.0, asks=False), Impl("aware", 20.0)]
    ev = evaluate(CFB, "r", both, {}, wait=20.0, unmet=unmet)
    assert ev.answer == Bid(A1, "r", 40.0, "aware", 20.0)
    assert bidding_after() is False  # only while a bid for later is priced


def test_an_implementation_without_a_bid_function_needs_no_detour() -> None:
    tree = Implementation("plain", CapabilityInterface("Count"), lambda: AlwaysSuccess("x"))
    ev = evaluate(CFB, "r", [tree], {}, wait=20.0, unmet=lambda i: None)
    assert isinstance(ev.answer, Bid)
    assert ev.answer.cost == 20.0 + tree.utility().expected_cost


def test_ties_go_to_the_first_name_and_broken_bid_functions_are_reported() -> None:
    impls = [Impl("z", 1.0), Impl("broken", 0.1, broken=True), Impl("m", 1.0)]
    ev = evaluate(CFB, "b", impls, {}, wait=0.0, unmet=unmet)
    assert ev.answer == Bid(A1, "b", 1.0, "m")
    assert [name for name, _ in ev.errors] == ["broken"]


def test_nobody_can_bid_says_why() -> None:
    impls = [Impl("x", None), Impl("y", 1.0, needs="precondition p (local) not met")]
    ev = evaluate(CFB, "b", impls, {}, wait=0.0, unmet=unmet)
    assert isinstance(ev.answer, NoBid)
    assert (
        ev.answer.reason == "x: cannot execute (its cost is None); precondition p (local) not met"
    )
    assert evaluate(CFB, "b", [], {}, wait=0.0, unmet=unmet).answer.reason == (  # type: ignore[union-attr]
        "no matching implementation"
    )


def test_body_runs_one_and_queues_at_most_one() -> None:
    e1, e2, e3 = (ExecutionId("a", "n", i) for i in (1, 2, 3))
    body = Body()
    assert body.wait_cost() == 0.0
    assert body.take(e1, 4.0)
    assert body.wait_cost() is None
    assert body.busy_reason() is not None
    assert body.release(e1) is None
    assert body.idle
    queue = Body(queue_after_current=True)
    queue.take(e1, 4.0)
    assert queue.wait_cost() == 4.0
    assert queue.take(e2, 1.0) is False
    assert queue.wait_cost() is None
    with pytest.raises(RuntimeError):
        queue.take(e3, 1.0)
    assert queue.release(e1) == e2
    assert queue.running == e2
    assert queue.wait_cost() == 1.0


def test_auction_answers_only_from_the_robot_they_speak_for() -> None:
    a = Auction(A1, "Count", frozenset({"b", "c"}), deadline=1.0)
    assert not a.offer(Bid(A1, "b", 0.0, "i"), sender="mallory")
    assert not a.offer(Bid(AuctionId("a", 2), "b", 0.0, "i"), sender="b")
    assert a.offer(Bid(A1, "b", 3.0, "i"), sender="b")
    assert not a.offer(Bid(A1, "b", 0.0, "i"), sender="b")  # once
    assert not a.closed(0.5)
    assert a.offer(NoBid(A1, "c", "busy"), sender="c")
    assert a.closed(0.5)
    assert [b.robot for b in a.outcome().awardable()] == ["b"]
    assert a.outcome().awardable(reserve=3.0) == []


def test_a_peers_reason_is_kept_bounded() -> None:
    a = Auction(A1, "Count", frozenset({"b"}), deadline=1.0)
    assert a.offer(NoBid(A1, "b", "x" * 1_000_000), sender="b")
    assert len(a.declined["b"]) == REASON_CHARS


def test_the_body_says_when_it_comes_free() -> None:
    freed: list[int] = []
    body = Body(queue_after_current=True, on_free=lambda: freed.append(1))
    e1, e2 = ExecutionId("a", "n", 1), ExecutionId("a", "n", 2)
    body.take(e1, 1.0)
    body.take(e2, 1.0)
    body.release(e1)  # the queued one takes over: not free
    assert freed == []
    body.release(e2)
    assert freed == [1]


def test_the_optimal_plan_beats_greedy_on_the_classic_trap() -> None:
    def bid(robot: str, cost: float) -> Bid:
        return Bid(A1, robot, cost, "i")

    t1 = [bid("b", 1.0), bid("c", 2.0)]
    t2 = [bid("b", 2.0), bid("c", 100.0)]
    assert optimal_plan([t1, t2], taken=set()) == ["c", "b"]  # 4, where greedy pays 101
    assert optimal_plan([t1, t2], taken={"b"}) == ["c", None]
    assert optimal_plan([[], t2], taken=set()) == [None, "b"]
    with pytest.raises(ValueError, match="expected one of auction, sequential, optimal"):
        check_strategy("fastest")


def test_a_fresh_estimate_of_the_running_work_is_what_a_queued_task_waits() -> None:
    body = Body(queue_after_current=True)
    running, queued = ExecutionId("o", "n", 1), ExecutionId("o", "n", 2)
    assert body.take(running, 80.0)
    assert body.wait_cost() == 80.0
    body.estimate(running, 12.5)  # the robot is nearly done
    assert body.wait_cost() == 12.5
    body.estimate(queued, 1.0)  # not held: no effect
    assert body.wait_cost() == 12.5
    assert not body.take(queued, 30.0)
    body.estimate(queued, 3.0)  # queued: priced from here, not after the running work
    assert body.release(running) == queued
    assert body.wait_cost() == 30.0


def test_a_busy_robot_bids_for_later_only_when_asked_and_it_is_never_awarded() -> None:
    body = Body()
    e1, e2 = ExecutionId("o", "n", 1), ExecutionId("o", "n", 2)
    assert body.committed_cost() == 0.0
    body.take(e1, 30.0)
    assert body.wait_cost() is None  # busy, no queue: no bid for now
    body.estimate(e1, 20.0)
    assert body.committed_cost() == 20.0  # what is left of its work
    # a time-extended call: what the task would cost after the 20 of work it holds
    later = evaluate(
        CFB, "r", [Impl("a", 5.0)], {}, wait=body.committed_cost(), unmet=unmet, later=True
    )
    assert later.answer == Bid(A1, "r", 25.0, "a", 20.0, later=True)
    now = evaluate(CFB, "s", [Impl("a", 7.0)], {}, wait=0.0, unmet=unmet)
    assert now.answer == Bid(A1, "s", 7.0, "a")
    auction = Auction(A1, "Count", frozenset({"r", "s"}), 1.0)
    for answer in (later.answer, now.answer):
        assert isinstance(answer, Bid)
        auction.offer(answer)
    outcome = auction.outcome()
    assert [b.robot for b in outcome.awardable()] == ["s"]
    assert [b.robot for b in outcome.later()] == ["r"]
    queued = Body(queue_after_current=True)
    queued.take(e1, 30.0)
    queued.take(e2, 4.0)
    assert queued.committed_cost() == 34.0
