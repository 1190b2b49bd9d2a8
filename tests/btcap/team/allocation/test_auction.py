"""The single-item auction: sans-IO rules, then the same rules between live agents."""

from __future__ import annotations

import asyncio
import math

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, silent_member, step, team, tick_until, until
from hypothesis import given
from hypothesis import strategies as st

from btcap import Parallel, ReactiveSequence, State
from btcap.actors import Actor, handler
from btcap.team.allocation.strategy import AuctionRecord
from btcap.team.core.auction import Auction
from btcap.team.ids import AuctionId
from btcap.team.messages import Award, AwardReply, Bid, CallForBids, CancelExecution, NoBid
from btcap.team.runtime.agent import Agent
from btcap.transports import Address

# -- sans-IO ------------------------------------------------------------------------------


A1 = AuctionId("a", 1)


def _auction(*robots: str, deadline: float = 10.0) -> Auction:
    return Auction(A1, "Count", frozenset(robots), deadline)


def test_closes_early_when_every_invited_robot_answered() -> None:
    auc = _auction("a", "b", "c")
    assert not auc.closed(0.0)
    assert auc.offer(Bid(A1, "a", 3.0, "i"))
    assert auc.offer(NoBid(A1, "b", "busy"))
    assert auc.waiting_for == {"c"}
    assert not auc.closed(9.9)
    assert auc.offer(Bid(A1, "c", 1.0, "j"))
    assert auc.closed(0.0)
    out = auc.outcome()
    assert [b.robot for b in out.ranking] == ["c", "a"]
    assert out.declined == {"b": "busy"}
    assert out.silent == frozenset()


def test_closes_at_the_window_when_someone_is_silent() -> None:
    auc = _auction("a", "b", deadline=5.0)
    auc.offer(Bid(A1, "a", 1.0, "i"))
    assert not auc.closed(4.99)
    assert auc.closed(5.0)
    out = auc.outcome()
    assert [b.robot for b in out.ranking] == ["a"]
    assert out.silent == {"b"}


def test_member_loss_closes_it() -> None:
    auc = _auction("a", "b")
    auc.offer(Bid(A1, "a", 1.0, "i"))
    auc.member_lost("z")  # not invited: changes nothing
    assert not auc.closed(0.0)
    auc.member_lost("b")
    assert auc.closed(0.0)
    assert auc.outcome().silent == frozenset()


def test_a_suspect_is_not_waited_for_but_its_answer_still_counts() -> None:
    auc = _auction("a", "b", "s")
    auc.excuse({"s", "z"})  # z: not invited, changes nothing
    auc.offer(Bid(A1, "a", 3.0, "i"))
    assert auc.waiting_for == {"b"}
    assert not auc.closed(0.0)
    assert auc.offer(Bid(A1, "s", 1.0, "j"))  # the suspect answered after all: it counts
    assert auc.offer(NoBid(A1, "b", "busy"))
    assert auc.closed(0.0)  # long before its deadline
    assert [b.robot for b in auc.outcome().ranking] == ["s", "a"]
    quiet = _auction("a", "s")
    quiet.excuse({"s"})
    quiet.offer(Bid(A1, "a", 3.0, "i"))
    assert quiet.closed(0.0)  # nobody but the suspect left to answer
    assert quiet.outcome().silent == frozenset()


def test_nobody_invited_is_closed_at_once_with_no_winner() -> None:
    auc = _auction()
    assert auc.closed(0.0)
    assert auc.outcome().ranking == []


def test_ranking_by_cost_then_robot_id() -> None:
    auc = _auction("a", "b", "c", "d")
    for robot, cost in (("d", 2.0), ("b", 1.0), ("c", 2.0), ("a", 2.0)):
        auc.offer(Bid(A1, robot, cost, f"impl-{robot}"))
    assert [b.robot for b in auc.outcome().ranking] == ["b", "a", "c", "d"]


@given(st.dictionaries(st.sampled_from("abcdef"), st.sampled_from([0.0, 1.0, 2.0]), min_size=1))
def test_ranking_does_not_depend_on_arrival_order(costs: dict[str, float]) -> None:
    ranks = []
    for order in (sorted(costs), sorted(costs, reverse=True)):
        auc = _auction(*costs)
        for robot in order:
            auc.offer(Bid(A1, robot, costs[robot], "i"))
        ranks.append([b.robot for b in auc.outcome().ranking])
    assert ranks[0] == ranks[1] == sorted(costs, key=lambda r: (costs[r], r))


@pytest.mark.parametrize("cost", [math.nan, math.inf, -math.inf, -0.5])
def test_invalid_costs_become_declines(cost: float) -> None:
    auc = _auction("a", "b")
    assert auc.offer(Bid(A1, "a", cost, "i"))
    auc.offer(Bid(A1, "b", 4.0, "j"))
    out = auc.outcome()
    assert [b.robot for b in out.ranking] == ["b"]
    assert "invalid cost" in out.declined["a"]
    assert auc.closed(0.0)


def test_zero_cost_is_a_valid_bid() -> None:
    auc = _auction("a")
    auc.offer(Bid(A1, "a", 0.0, "i"))
    assert [b.cost for b in auc.outcome().ranking] == [0.0]


def test_late_duplicate_and_foreign_answers_are_ignored() -> None:
    auc = _auction("a", "b")
    assert auc.offer(Bid(A1, "a", 2.0, "i"))
    assert not auc.offer(Bid(A1, "a", 0.1, "i"))  # a second answer from a
    assert not auc.offer(NoBid(A1, "a", "changed my mind"))
    assert not auc.offer(Bid(AuctionId("a", 2), "b", 0.1, "j"))  # another auction's bid
    assert not auc.offer(Bid(A1, "zed", 0.1, "k"))  # never invited
    assert auc.waiting_for == {"b"}
    assert [(b.robot, b.cost) for b in auc.outcome().ranking] == [("a", 2.0)]


# -- between agents -----------------------------------------------------------------------


async def test_auction_between_agents_closes_early_and_cheapest_wins() -> None:
    # A window of 1000 clock seconds (100 s of wall time): only an early close can finish.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=1000.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", 2.0, probe)])
            await t.add("c", [count_impl("c", 3.0, probe)])
            await t.add("d")  # no implementation: not even invited
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.assignments == ["b"]
            out = a.allocator.outcomes[-1]
            assert out is not None
            assert [(b.robot, b.cost) for b in out.ranking] == [("b", 2.0), ("c", 3.0), ("a", 5.0)]
            assert out.silent == frozenset()
            assert out.declined == {}
            assert a.allocator.stats.early_closes == a.allocator.stats.auctions == 1
            assert a.allocator.stats.awarded == 1
            await tree.shutdown()


async def test_equal_costs_are_broken_by_robot_id() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            c = await t.add("c", [count_impl("c", 2.0, probe)])
            await t.add("b", [count_impl("b", 2.0, probe)])
            await t.add("d", [count_impl("d", 2.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = c.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.assignments == ["b"]
            await tree.shutdown()


@pytest.mark.parametrize("real_time", [False, True], ids=["virtual", "wall"])
async def test_a_silent_member_holds_the_auction_until_the_window_ends(real_time: bool) -> None:
    # On the wall a loop timer ends the window; on a virtual clock, ``within``.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=2.0, real_time=real_time) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            async with silent_member(t.net, "s", [count_impl("s", 0.1, probe)], t.clock):
                await knows(a, "s")
                node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                start = t.clock.now()
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                # the auction waited its whole window (on the wall: to the timer's resolution)
                assert t.clock.now() - start >= 2.0 - (1e-3 if real_time else 0.0)
                out = a.allocator.outcomes[-1]
                assert out is not None
                assert out.silent == {"s"}
                assert [b.robot for b in out.ranking] == ["a"]
                assert a.allocator.stats.early_closes == 0
                assert node.assignments == ["a"]
                await tree.shutdown()


async def test_a_member_leaving_closes_the_auction_it_was_silent_in() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=1000.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            async with silent_member(t.net, "s", [count_impl("s", 0.1, probe)], t.clock):
                await knows(a, "s")
                node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                tree.tick()
                await until(lambda: bool(a.allocator._open), "the auction to open")
                auction, _done = next(iter(a.allocator._open.values()))
                await until(lambda: auction.waiting_for == {"s"}, "a's own bid")
            # s said goodbye: the auction stops waiting for it, long before its window.
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            out = a.allocator.outcomes[-1]
            assert out is not None
            assert out.silent == frozenset()
            assert node.assignments == ["a"]
            await tree.shutdown()


async def test_no_auction_waits_for_a_suspected_member() -> None:
    # s goes quiet (isolated): once a suspects it, an auction still open stops waiting for
    # it, and one opened later never waits for it, long before s is declared failed.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=1000.0, failure_timeout_s=500.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            async with silent_member(
                t.net, "s", [count_impl("s", 0.1, probe)], t.clock, failure_timeout_s=500.0
            ):
                await knows(a, "s")
                for first in (True, False):
                    node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                    tree = a.mission(ReactiveSequence("root", children=[node]))
                    start = t.clock.now()
                    if first:  # open before the suspicion
                        tree.tick()
                        await until(lambda: bool(a.allocator._open), "the auction to open")
                        opened, _done = next(iter(a.allocator._open.values()))
                        await until(lambda: opened.waiting_for == {"s"}, "a's own bid")  # noqa: B023
                        t.net.isolate("s")
                    else:  # opened while s is suspected
                        assert "s" in a.team.suspected()
                    status = await tick_until(tree, lambda s: s is not State.RUNNING)
                    assert status is State.SUCCEEDED
                    assert node.assignments == ["a"]
                    assert t.clock.now() - start < 100.0  # neither window nor failure
                    assert "s" in a.team.suspected()  # still a member, suspected
                    await tree.shutdown()


async def test_invalid_bids_from_a_robot_are_declines_and_the_next_wins() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("n", [count_impl("n", math.nan, probe)])
            await t.add("m", [count_impl("m", -1.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.assignments == ["a"]
            out = a.allocator.outcomes[-1]
            assert out is not None
            assert set(out.declined) == {"n", "m"}
            assert all("invalid cost" in why for why in out.declined.values())
            await tree.shutdown()


async def test_robot_declines_when_its_bid_function_says_it_cannot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", lambda inp: None if inp["x"] > 10 else 1.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 11, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            out = a.allocator.outcomes[-1]
            assert out is not None
            why = "count-b: cannot execute these inputs: its bid function returned None"
            assert out.declined["b"] == why  # whose decision it was
            assert node.assignments == ["a"]
            await tree.shutdown()


async def test_busy_winner_declines_the_award_and_the_next_bidder_gets_it() -> None:
    # Two origins auction at once; s never answers, so both auctions run their whole
    # window and both rank b first. b accepts the first award and declines the second,
    # which falls through to the next bid.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=1.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            c = await t.add("c", [count_impl("c", 4.0, probe)])
            async with silent_member(t.net, "s", [count_impl("s", 9.0, probe)], t.clock):
                await until(
                    lambda: all(
                        x.repository.providers(COUNT.identity) == {"a", "b", "c", "s"}
                        and len(x.team.alive()) == 4
                        for x in (a, b, c)
                    ),
                    "the team to converge",
                )
                na = COUNT.node_type()("count", inputs={"x": 1})
                nc = COUNT.node_type()("count", inputs={"x": 2})
                ta = a.mission(ReactiveSequence("ra", children=[na]))
                tc = c.mission(ReactiveSequence("rc", children=[nc]))
                ta.tick()
                tc.tick()
                await until(
                    lambda: (
                        na.execution is None
                        and nc.execution is None
                        and a.allocator.stats.auctions == c.allocator.stats.auctions == 1
                    ),
                    "both auctions",
                )
                for _ in range(1000):
                    ta.tick()
                    tc.tick()
                    if na.state is State.RUNNING and nc.state is State.RUNNING:
                        break
                    await step(0.005)
                robots = sorted([*na.assignments, *nc.assignments])
                assert "b" in robots
                assert len(robots) == 2
                assert robots[0] != robots[1]
                assert b.mission_control.stats.declined == 1
                stats = [a.allocator.stats, c.allocator.stats]
                assert sum(s.declined_awards for s in stats) == 1
                assert sum(s.awarded for s in stats) == 2
                for node in (na, nc):
                    node.set_input("stop", True)
                for tree in (ta, tc):
                    assert (
                        await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                    )
                await ta.shutdown()
                await tc.shutdown()


async def knows(a: Agent, other: str) -> None:
    """``a`` sees ``other`` alive and offering Count (a member that never answers bids)."""

    def ok() -> bool:
        return a.repository.providers(COUNT.identity) == {"a", other} and other in a.team.alive()

    await until(ok, f"a to know {other}")


class SlowExecutor(Actor):
    """A scripted mission control: bids low, takes its time to answer awards (accepting
    them in the end), and records cancellations."""

    def __init__(self, robot: str, cost: float) -> None:
        super().__init__()
        self.robot, self.cost = robot, cost
        self.release = asyncio.Event()
        self.awards: list[Award] = []
        self.cancels: list[CancelExecution] = []

    @handler
    def on_call(self, msg: CallForBids) -> None:
        self.system.ref(Address(msg.auction.auctioneer, "auctioneer")).tell(
            Bid(msg.auction, self.robot, self.cost, "count-f")
        )

    @handler
    async def on_award(self, msg: Award) -> AwardReply:
        self.awards.append(msg)
        await self.release.wait()
        return AwardReply(msg.execution, self.robot, True)

    @handler
    def on_cancel(self, msg: CancelExecution) -> None:
        self.cancels.append(msg)


@pytest.mark.parametrize("real_time", [False, True], ids=["virtual", "wall"])
async def test_an_award_that_timed_out_is_withdrawn_and_goes_to_the_next_bidder(
    real_time: bool,
) -> None:
    # On the wall the award ask's own limit ends the wait; on a virtual clock, ``within``.
    with anyio.fail_after(10):
        probe = Probe()
        records: list[AuctionRecord] = []
        async with team(award_timeout_s=0.5, real_time=real_time) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            slow = SlowExecutor("f", 1.0)
            async with silent_member(
                t.net, "f", [count_impl("f", 1.0, probe)], t.clock, {"mission_control": slow}
            ):
                await knows(a, "f")
                a.allocator.watch(records.append)
                node = COUNT.node_type()("count", inputs={"x": 1})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
                assert node.assignments == ["a"]
                why = "no reply from f/mission_control to the award within 0.5 clock s"
                assert records[-1].passed["f"] == f"no answer to the award ({why})"
                assert [w.execution for w in slow.awards] == [node.execution.id]  # type: ignore[union-attr]
                assert a.allocator.stats.declined_awards == 1
                # f finally takes the award, too late: the withdrawal follows right behind.
                slow.release.set()
                await until(lambda: bool(slow.cancels), "the withdrawal")
                assert slow.cancels[0].execution == slow.awards[0].execution
                await tree.shutdown()


async def test_an_award_in_flight_is_withdrawn_when_the_capability_is_reset() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(award_timeout_s=1000.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            slow = SlowExecutor("f", 1.0)
            async with silent_member(
                t.net, "f", [count_impl("f", 1.0, probe)], t.clock, {"mission_control": slow}
            ):
                await knows(a, "f")
                node = COUNT.node_type()("count", inputs={"x": 1})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                tree.tick()
                await until(lambda: bool(slow.awards), "the award to f")
                tree.reset()
                slow.release.set()
                await until(lambda: bool(slow.cancels), "the withdrawal")
                assert slow.cancels[0].execution == slow.awards[0].execution
                assert node.assignments == []
                assert node.execution is None
                assert a.mission_control.body.running is None
                assert not a.mission_control.origin.tracked
                await tree.shutdown()


async def test_simultaneous_auctions_award_the_cheapest_pair_first() -> None:
    """Two tasks wait for the one robot: it gets the one it does cheapest, although the
    other's auction was opened (and closed) first."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", lambda inputs: float(inputs["x"]), probe)])
            await t.converged()
            far = COUNT.node_type()("far", inputs={"x": 5})
            near = COUNT.node_type()("near", inputs={"x": 1})
            tree = a.mission(Parallel("both", children=[far, near]))
            await tick_until(tree, lambda _s: State.RUNNING in (far.state, near.state), "one")
            assert (near.state, far.state) == (State.RUNNING, State.UNASSIGNED)
            assert [o.ranking[0].cost for o in a.allocator.outcomes] == [5.0, 1.0]
            await tree.shutdown()


async def test_a_robot_takes_one_task_per_batch_even_with_a_queue() -> None:
    """b bids 10 for both, c 11: one each. Queued behind its first, b's second would
    really cost 20, not the 10 it bid while idle."""
    with anyio.fail_after(20):
        probe = Probe()
        async with team(queue_after_current=True, reevaluate_s=None) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 10.0, probe)])
            await t.add("c", [count_impl("c", 11.0, probe)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 1})
            n2 = COUNT.node_type()("n2", inputs={"x": 2})
            tree = a.mission(Parallel("both", children=[n1, n2]))
            await tick_until(tree, lambda _s: bool(n1.assignments and n2.assignments), "both")
            assert sorted(n1.assignments + n2.assignments) == ["b", "c"]
            await tree.shutdown()


@pytest.mark.parametrize(
    ("strategy", "total"),
    [("arrival", 101.0), ("auction", 4.0), ("sequential", 4.0), ("optimal", 4.0)],
)
async def test_strategies_award_the_same_batch_their_own_way(strategy: str, total: float) -> None:
    """The classic trap: awarded as they close, b gets its cheapest task and c the other
    at 100; the auction awards the task that would lose most by waiting first (regret),
    the sequential plan exchanges the greedy pair's robots, the optimal plan is least."""
    costs = {"b": {1: 1.0, 2: 2.0}, "c": {1: 2.0, 2: 100.0}}
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy=strategy, reevaluate_s=None) as t:
            a = await t.add("a")
            for robot, by_task in costs.items():
                bid = lambda inputs, c=by_task: c[inputs["x"]]  # noqa: E731
                await t.add(robot, [count_impl(robot, bid, probe)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 1})
            n2 = COUNT.node_type()("n2", inputs={"x": 2})
            tree = a.mission(Parallel("both", children=[n1, n2]))
            await tick_until(tree, lambda _s: bool(n1.assignments and n2.assignments), "both")
            paid = costs[n1.assignments[0]][1] + costs[n2.assignments[0]][2]
            assert paid == total
            await tree.shutdown()
