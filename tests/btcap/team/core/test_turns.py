"""The order closed auctions award in (the :class:`AwardQueue`), on explicit time."""

from __future__ import annotations

import pytest

from btcap.team.core.auction import Auction
from btcap.team.core.task import AssignmentTask
from btcap.team.core.turns import ARRIVAL, AUCTION, OPTIMAL, SEQUENTIAL, AwardQueue, BatchPolicy
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Bid

A1, A2, A3 = AuctionId("o", 1), AuctionId("o", 2), AuctionId("o", 3)


def task(number: int) -> AssignmentTask:
    return AssignmentTask(ExecutionId("o", "n", number), "Move", "move", {}, frozenset(), 1.0)


def auction(queue: AwardQueue, aid: AuctionId, deadline: float, **costs: float) -> Auction:
    """An auction opened in ``queue`` that invites ``costs``' robots, who bid them."""
    a = Auction(aid, "Move", frozenset(costs), deadline)
    queue.opened(aid, a.invited)
    for robot, cost in costs.items():
        a.offer(Bid(aid, robot, cost, "i"))
    return a


def close(queue: AwardQueue, a: Auction, now: float, reserve: float | None = None) -> None:
    assert a.closed(now)
    queue.closed(a.id, a.outcome(), reserve)


def award_to(queue: AwardQueue, aid: AuctionId, robot: str) -> None:
    """``aid`` (whose turn it is) is accepted by ``robot``."""
    queue.took(robot)
    queue.finished(aid)


def test_a_closed_auction_waits_for_an_open_competitor_then_regret_orders() -> None:
    queue = AwardQueue(AUCTION)
    first = auction(queue, A1, 1.0, a=1.0, b=5.0)  # loses 4 if it waits
    second = auction(queue, A2, 2.0, a=2.0, b=2.5)  # loses 0.5
    close(queue, first, now=1.0)
    assert queue.next_turn() is None  # A2 still collects bids from a and b
    close(queue, second, now=2.0)
    assert queue.next_turn() == A1  # the bigger regret first, though A2 is cheaper for a
    assert queue.next_turn() is None  # one at a time
    assert queue.round(A1, task(1)).next() is not None
    award_to(queue, A1, "a")
    assert queue.next_turn() == A2
    award = queue.round(A2, task(2))
    assert award.reasons == {"a": "took another task of the same round"}
    nxt = award.next()
    assert nxt is not None
    assert award.offered.robot == "b"
    assert award.next() is None  # a is skipped
    queue.finished(A2)
    assert queue.taken == set()  # the batch is over: a bids again


def test_an_open_auction_for_other_robots_does_not_hold_a_turn() -> None:
    queue = AwardQueue(AUCTION)
    close(queue, auction(queue, A1, 1.0, a=1.0), now=1.0)
    auction(queue, A2, 9.0, c=1.0)
    assert queue.next_turn() == A1


def test_arrival_awards_each_auction_as_it_closes_oldest_first() -> None:
    queue = AwardQueue(ARRIVAL)
    first = auction(queue, A1, 1.0, a=3.0)
    second = auction(queue, A2, 2.0, a=1.0)
    auction(queue, A3, 3.0, a=0.5)  # open, competing: arrival does not wait
    close(queue, first, now=1.0)
    close(queue, second, now=2.0)
    assert queue.next_turn() == A1
    queue.finished(A1)
    assert queue.next_turn() == A2


def test_a_plan_puts_its_robot_first_and_the_cheapest_planned_awards_first() -> None:
    queue = AwardQueue(OPTIMAL)
    first = auction(queue, A1, 1.0, a=1.0, b=2.0)
    second = auction(queue, A2, 1.0, a=1.5, b=10.0)
    close(queue, first, now=1.0)
    close(queue, second, now=1.0)
    # The optimum gives A1 to b and A2 to a (3.5 in all, not 11): A2's 1.5 goes first.
    assert queue.next_turn() == A2
    award = queue.round(A2, task(2))
    assert award.next() is not None
    assert award.offered.robot == "a"
    award_to(queue, A2, "a")
    assert queue.next_turn() == A1
    award = queue.round(A1, task(1))
    assert award.next() is not None
    assert award.offered.robot == "b"
    assert award.next() is None
    assert award.reasons == {"a": "took another task of the same round"}


@pytest.mark.parametrize("policy", [AUCTION, SEQUENTIAL, OPTIMAL, ARRIVAL])
def test_ties_go_to_the_oldest_closed_auction(policy: BatchPolicy) -> None:
    queue = AwardQueue(policy)
    first = auction(queue, A1, 1.0, a=1.0)
    second = auction(queue, A2, 1.0, a=1.0)
    close(queue, second, now=1.0)
    close(queue, first, now=1.0)
    assert queue.next_turn() == A2


def test_a_reserve_keeps_bids_not_below_it_from_the_award() -> None:
    queue = AwardQueue(AUCTION)
    close(queue, auction(queue, A1, 1.0, a=1.0, b=3.0), now=1.0, reserve=2.0)
    assert queue.next_turn() == A1
    award = queue.round(A1, task(1))
    assert award.reasons == {"b": "bid 3 not below 2"}
    assert award.next() is not None
    assert award.offered.robot == "a"
    assert award.next() is None


def test_an_auction_given_up_frees_the_turn() -> None:
    queue = AwardQueue(AUCTION)
    close(queue, auction(queue, A1, 1.0, a=1.0), now=1.0)
    auction(queue, A2, 5.0, a=1.0)
    close(queue, auction(queue, A3, 1.0, a=2.0), now=1.0)
    assert queue.next_turn() is None
    queue.finished(A1)  # cancelled while waiting
    assert queue.waiting == [A3]
    queue.dropped(A2)  # cancelled while collecting bids
    assert queue.next_turn() == A3
    assert queue.awarding == A3
    with pytest.raises(ValueError, match="not the one awarding"):
        queue.round(A1, task(1))
    queue.finished(A3)  # cancelled while awarding
    assert queue.awarding is None
    assert queue.next_turn() is None


def test_an_extended_policy_plans_with_bids_for_later_but_never_awards_them() -> None:
    queue = AwardQueue(OPTIMAL)
    assert getattr(OPTIMAL, "extended", False)
    near = Auction(A1, "Move", frozenset({"f", "b"}), 1.0)
    far = Auction(A2, "Move", frozenset({"f", "c"}), 1.0)
    for a, bids in (
        (
            near,
            [Bid(A1, "f", 10.0, "i"), Bid(A1, "b", 12.0, "i", 5.0, later=True)],
        ),  # b: 12 after 5
        (far, [Bid(A2, "f", 50.0, "i"), Bid(A2, "c", 200.0, "i", 100.0, later=True)]),
    ):
        queue.opened(a.id, a.invited)
        for b in bids:
            assert a.offer(b)
        close(queue, a, 1.0)
    # f takes the far task; the near one, cheaper for f, waits for b and does not take
    # f first (a task the plan leaves waiting never takes a robot planned for another)
    assert queue.next_turn() == A2
    assert queue.round(A2, task(2)).next() is not None
    award_to(queue, A2, "f")
    assert queue.next_turn() == A1
    round_ = queue.round(A1, task(1))
    assert round_.next() is None  # b's bid for later is not awarded, f is taken
    assert "busy" in round_.result().reasons["b"]


def test_off_the_loop_a_batch_of_two_is_planned_by_the_caller_and_one_at_once() -> None:
    """The caller plans a batch of more than one auction (in a worker thread) and hands
    the plan back; no auction awards meanwhile. A batch of one is planned at once."""
    queue = AwardQueue(OPTIMAL, off_loop=True)
    close(queue, auction(queue, A1, 1.0, a=1.0, b=2.0), now=1.0)
    assert queue.next_turn() == A1  # alone: planned at once, no job
    assert queue.planning() is None
    award_to(queue, A1, "a")
    first = auction(queue, A2, 2.0, a=1.0, b=1.5)
    second = auction(queue, A3, 2.0, a=1.0, b=9.0)  # only a does it well
    close(queue, first, now=2.0)
    close(queue, second, now=2.0)
    assert queue.next_turn() is None
    job = queue.planning()
    assert job is not None
    assert len(job.bids) == 2
    assert queue.planning() is None  # handed out once
    assert queue.next_turn() is None  # its plan is being made
    assert queue.planned(job, OPTIMAL.plan(job.bids, job.taken))
    assert queue.next_turn() == A3  # the cheapest award first: a for A3, as planned
    award = queue.round(A3, task(3))
    assert award.next() is not None
    assert award.offered.robot == "a"


def test_a_plan_for_a_batch_that_changed_meanwhile_is_dropped_and_made_again() -> None:
    queue = AwardQueue(OPTIMAL, off_loop=True)
    close(queue, auction(queue, A1, 1.0, a=1.0, b=2.0), now=1.0)
    close(queue, auction(queue, A2, 1.0, a=1.0, b=3.0), now=1.0)
    assert queue.next_turn() is None
    old = queue.planning()
    assert old is not None
    queue.finished(A2)  # given up while waiting for its turn
    assert not queue.planned(old, ["b", "a"])
    assert queue.next_turn() == A1  # a batch of one now: planned at once
    award = queue.round(A1, task(1))
    assert award.next() is not None
    assert award.offered.robot == "a"
