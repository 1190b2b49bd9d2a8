"""Every strategy between live agents on the manual clock: no allocation waits for a
robot suspected of failure, and one that refutes the suspicion is invited again."""

from __future__ import annotations

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, silent_member, team, tick_until, until

from btcap import ReactiveSequence, State
from btcap.team.allocation.strategies import BUILTIN
from btcap.team.allocation.strategy import AuctionRecord
from btcap.team.runtime.agent import Agent


async def _run(a: Agent) -> list[str]:
    """A task only ``a`` and ``s`` can run, to its end: who ran it."""
    node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
    tree = a.mission(ReactiveSequence("root", children=[node]))
    status = await tick_until(tree, lambda s: s is not State.RUNNING)
    assert status is State.SUCCEEDED
    await tree.shutdown()
    return list(node.assignments)


@pytest.mark.parametrize("strategy", sorted(BUILTIN))
async def test_a_suspect_holds_nothing_up_and_is_invited_again_once_back(strategy: str) -> None:
    """s (cheaper than a) is cut off: once a suspects it, a's task goes to a without
    waiting for s (a window of 1000 s, s declared failed after 500 s); once s refutes
    the suspicion, the next task waits for its answer again, and s wins it."""
    with anyio.fail_after(30):
        probe = Probe()
        cfg = {"reevaluate_s": None, "auction_window_s": 1000.0, "failure_timeout_s": 500.0}
        async with team(strategy=strategy, **cfg) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("s", [count_impl("s", 1.0, probe)])
            await t.converged()
            await until(lambda: a.repository.providers(COUNT.identity) == {"a", "s"})
            t.net.isolate("s")
            await until(lambda: "s" in a.team.suspected(), "a to suspect s")
            start = t.clock.now()
            assert await _run(a) == ["a"]
            assert t.clock.now() - start < 100.0  # neither the window nor s's failure
            assert "s" in a.team.suspected()
            t.net.heal("s")
            await until(lambda: "s" not in a.team.suspected(), "s to refute the suspicion")
            assert "s" in a.team.alive()  # never declared failed
            assert await _run(a) == ["s"]
            assert not probe.violations


@pytest.mark.parametrize("strategy", ["arrival", "auction", "optimal", "sequential"])
async def test_a_suspects_bid_is_awarded_only_after_the_others(strategy: str) -> None:
    """s bids cheapest, then is cut off and suspected while the auction waits for c
    (silent): when it closes, a is asked first and takes the task; s is never asked, so
    the award does not wait the award timeout on a robot likely gone."""
    with anyio.fail_after(30):
        probe = Probe()
        cfg = {"reevaluate_s": None, "auction_window_s": 50.0, "failure_timeout_s": 500.0}
        async with team(strategy=strategy, **cfg) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("s", [count_impl("s", 1.0, probe)])
            async with silent_member(
                t.net, "c", [count_impl("c", 9.0, probe)], t.clock, failure_timeout_s=500.0
            ):
                providers = {"a", "s", "c"}
                await until(lambda: a.repository.providers(COUNT.identity) == providers)
                records: list[AuctionRecord] = []
                a.allocator.watch(records.append)
                node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                tree.tick()
                await until(lambda: bool(a.allocator._open), "the auction to open")
                auction, _done = next(iter(a.allocator._open.values()))
                await until(lambda: auction.waiting_for == {"c"}, "a's and s's bids")
                t.net.isolate("s")
                await until(lambda: "s" in a.team.suspected(), "a to suspect s")
                status = await tick_until(tree, lambda s: s is not State.RUNNING)
                assert status is State.SUCCEEDED
                assert node.assignments == ["a"]
                ended = [r for r in records if r.result is not None]
                assert [b.robot for b in ended[0].outcome.ranking] == ["s", "a"]  # type: ignore[union-attr]
                assert "s" not in ended[0].passed  # never asked
                await tree.shutdown()
            assert not probe.violations
