"""A member acting in its own name is still bounded (issue 19, item 5): awards only for
auctions the robot bid in, leases no longer than ``max_lease_s``, calls for bids and the
news that sets off re-evaluation budgeted per member."""

from __future__ import annotations

from typing import Any

import anyio
import pytest
from capfixtures import COUNT, SPEEDUP, Probe, count_impl, step, team, tick_until

from btcap import ReactiveSequence, State
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award, AwardReply, CallForBids, Heartbeat
from btcap.team.runtime.executor import CALLS_BURST
from btcap.transports import Address

MC = "mission_control"


def _award(auction: AuctionId, number: int, lease_s: float) -> Award:
    execution = ExecutionId(auction.auctioneer, "root/count", number)
    return Award(auction, execution, "Count", "count-b", {"x": 1}, lease_s)


@pytest.mark.parametrize("strategy", ["auction", "consensus"])
async def test_an_award_no_auction_preceded_is_declined_and_the_robot_stays_free(
    strategy: str,
) -> None:
    """Whatever the strategy: b bid in no auction of x's and claimed none of its tasks."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy=strategy) as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            x = await t.add("x")
            await t.converged()
            reply = await x.system.ref(Address("b", MC)).ask(
                _award(AuctionId("x", 1), 1, 1e6), expect=AwardReply
            )
            assert not reply.accepted
            assert "we made no bid in auction x#1" in reply.reason
            assert b.mission_control.body.idle
            # The next mission still finds b.
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running on b")
            assert node.assignments == ["b"]
            await tree.shutdown()


async def test_a_lease_over_max_lease_s_is_declined_after_a_real_bid() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(max_lease_s=60.0) as t:
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            x = await t.add("x")
            await t.converged()
            # x calls for bids like an auctioneer: b bids, so x's award is one b asked for.
            cfbs = [AuctionId("x", n) for n in (1, 2)]
            for auction in cfbs:
                x.system.tell(
                    Address("b", MC), CallForBids(auction, "Count", COUNT.identity, {"x": 1})
                )
            await step()
            ask = x.system.ref(Address("b", MC))
            reply = await ask.ask(_award(cfbs[0], 1, 1e6), expect=AwardReply)
            assert not reply.accepted
            assert "lease_s 1e+06 is over this robot's max_lease_s 60" in reply.reason
            assert b.mission_control.body.idle
            reply = await ask.ask(_award(cfbs[1], 2, 2.0), expect=AwardReply)
            assert reply.accepted, reply.reason
            # One award per auction: the same auction cannot tie b up a second time.
            reply = await ask.ask(_award(cfbs[1], 3, 2.0), expect=AwardReply)
            assert not reply.accepted
            assert "no bid" in reply.reason


async def test_calls_for_bids_beyond_a_members_budget_are_not_priced() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            x = await t.add("x")
            await t.converged()
            mc = b.mission_control
            refused = mc.stats.refused
            n = int(CALLS_BURST) + 100
            for k in range(n):
                cfb = CallForBids(AuctionId("x", k + 1), "Count", COUNT.identity, {"x": 1})
                x.system.tell(Address("b", MC), cfb)
            await step()
            assert mc.stats.refused - refused >= 90
            assert len(mc.executor.bids) <= CALLS_BURST + 10
            assert mc.executor.calls.refused >= 90


@pytest.mark.parametrize("strategy", ["auction", "consensus"])
async def test_a_flipping_busy_flag_sets_off_few_re_evaluations(strategy: str) -> None:
    """300 heartbeats in 3 clock seconds, the busy flag flipped in each: the origin's
    re-evaluations (an auction per running task) stay within the news budget."""
    with anyio.fail_after(20):
        probe = Probe()
        cfg: dict[str, Any] = {"strategy": strategy, "reevaluate_s": 1000.0}
        cfg["auction_window_s"] = 1.0  # the budget: one piece of news per window
        async with team(**cfg) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 1.05, probe)])
            x = await t.add("x")
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            auctions = a.allocator.stats.auctions
            beat = x.team.beat + 1000
            for k in range(300):
                hb = Heartbeat("x", x.team.incarnation, x.repository.version, k % 2 == 0, beat + k)
                x.system.tell(Address("a", "team"), hb)
                tree.tick()
                await step(0.01 / SPEEDUP)  # 10 ms of clock time
            for _ in range(20):
                tree.tick()
                await step()
            held = a.allocator.stats.auctions - auctions
            assert 1 <= held <= 12, held  # a burst of 4, then one a second; not 150
            assert a.mission_control.stats.news_ignored >= 100
            assert node.assignments == ["b"]
            await tree.shutdown()
