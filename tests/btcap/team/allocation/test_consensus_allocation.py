"""The consensus strategy between live agents on the manual clock: no auctioneer, awards
still confirmed, and a member lost mid-consensus has its work re-allocated."""

from __future__ import annotations

from typing import Any

import anyio
from capfixtures import (
    COUNT,
    Probe,
    count_impl,
    silent_member,
    step,
    team,
    tick_until,
    until,
)

from btcap import Parallel, ReactiveSequence, State
from btcap.team.allocation.auction import Assigned, AssignmentTask, AuctionRecord, Unassigned
from btcap.team.allocation.consensus import ConsensusAssigner
from btcap.team.ids import ExecutionId
from btcap.team.messages import ConsensusClaim, ConsensusTasks, Heartbeat, OpenTask
from btcap.transports import BROADCAST, Address
from btcap.transports.codec import Envelope


def _cons(agent: object) -> ConsensusAssigner:
    allocator = getattr(agent, "allocator", None)
    assert isinstance(allocator, ConsensusAssigner)
    return allocator


async def test_a_mission_completes_with_the_cheapest_robot_and_no_auctioneer() -> None:
    # A window of 1000 clock seconds: only agreement can finish it in time.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy="consensus", auction_window_s=1000.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", 2.0, probe)])
            await t.add("c", [count_impl("c", 3.0, probe)])
            await t.add("d")  # no implementation: takes part, claims nothing
            await t.converged()
            seen: list[AuctionRecord] = []
            _cons(a).watch(seen.append)
            node = COUNT.node_type()("count", inputs={"x": 3, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.assignments == ["b"]
            assert node.outputs["y"] == 3
            assert [r.closed is None for r in seen] == [True, False]
            assert seen[1].outcome is not None
            assert [(b.robot, b.cost) for b in seen[1].outcome.ranking] == [("b", 2.0)]
            assert seen[1].result == Assigned("b", "count-b", 2.0)
            stats = _cons(a).stats
            assert stats.awarded == stats.early_closes == stats.auctions == 1
            assert stats.refused == stats.dropped == 0
            assert not probe.violations
            await tree.shutdown()


async def test_parallel_tasks_escape_the_greedy_trap() -> None:
    """The greedy trap: b does task 1 cheapest, but giving it task 1 leaves task 2 to c
    at 100; the auction gives b task 2 and c task 1 (4 in all, not 101)."""
    costs = {"b": {1: 1.0, 2: 2.0}, "c": {1: 2.0, 2: 100.0}}
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None) as t:
            a = await t.add("a")
            for robot, by_task in costs.items():
                bid = lambda inputs, c=by_task: c[inputs["x"]]  # noqa: E731
                await t.add(robot, [count_impl(robot, bid, probe)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 1})
            n2 = COUNT.node_type()("n2", inputs={"x": 2})
            tree = a.mission(Parallel("both", children=[n1, n2]))
            await tick_until(tree, lambda _s: bool(n1.assignments and n2.assignments), "both")
            assert (n1.assignments, n2.assignments) == (["c"], ["b"])
            assert _cons(a).stats.declined_awards == 0
            await tree.shutdown()


async def test_two_origins_never_award_the_same_robot() -> None:
    """Two robots with mission trees and one worker: separate auctions would both try
    it; under consensus one task waits, and runs when the worker is free again."""
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None) as t:
            o1 = await t.add("o1")
            o2 = await t.add("o2")
            await t.add("w", [count_impl("w", 1.0, probe, after=3)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 1})
            n2 = COUNT.node_type()("n2", inputs={"x": 2})
            t1 = o1.mission(ReactiveSequence("r1", children=[n1]))
            t2 = o2.mission(ReactiveSequence("r2", children=[n2]))
            for _ in range(2000):
                s1, s2 = t1.tick(), t2.tick()
                if s1 is State.SUCCEEDED and s2 is State.SUCCEEDED:
                    break
                await step()
            assert (n1.assignments, n2.assignments) == (["w"], ["w"])
            assert not probe.violations
            declined = _cons(o1).stats.declined_awards + _cons(o2).stats.declined_awards
            assert declined == 0  # the consensus kept them apart, not a refusal
            await t1.shutdown()
            await t2.shutdown()


async def test_a_winner_lost_mid_consensus_has_its_task_reallocated() -> None:
    """b claims the task while the team cannot agree yet (candidate s never speaks), then
    fails silently: its claim goes with it, c claims the task, and once s has left the
    team agrees and c runs it. b never gets an award."""
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None, auction_window_s=1000.0) as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 2.0, probe, after=3)])
            everyone = {"a", "b", "c", "s"}
            # s could run it (dearly) but never bids: the team cannot agree while it is there
            async with silent_member(t.net, "s", [count_impl("s", 9.0, probe)], t.clock):
                await until(lambda: all(x.team.alive() == everyone for x in t.agents.values()))
                await until(lambda: len(a.repository.providers(COUNT.identity)) == 3)
                node = COUNT.node_type()("count", inputs={"x": 1})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                core = _cons(a).core

                def winner() -> str | None:
                    won = list(core.winners().values())
                    return won[0].robot if won else None

                await tick_until(tree, lambda _s: winner() == "b", "b to claim it")
                for actor in (b.allocator, b.mission_control, b.team):
                    b.system.stop(actor)  # silent from now on: the team declares it failed
                await tick_until(tree, lambda _s: "b" not in core.members, "b to be lost")
                await tick_until(tree, lambda _s: winner() == "c", "c to claim it")
                assert node.state is State.UNASSIGNED
                assert not core.converged()
            state = await tick_until(tree, lambda s: s in (State.SUCCEEDED, State.FAILED))
            assert state is State.SUCCEEDED
            assert node.assignments == ["c"]
            assert probe.ticks["b"] == 0
            assert _cons(a).stats.declined_awards == 0
            await tree.shutdown()


async def test_a_robot_lost_mid_run_has_its_work_reassigned_through_consensus() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 2.0, probe, after=5)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: probe.ticks["b"] > 0, "b running")
            await t.remove("b")
            state = await tick_until(tree, lambda s: s in (State.SUCCEEDED, State.FAILED))
            assert state is State.SUCCEEDED
            assert node.assignments == ["b", "c"]
            assert not probe.violations
            await tree.shutdown()


async def test_work_stays_with_a_robot_beaten_by_less_than_the_margin() -> None:
    """c bids 10 % below b, the margin asks for 20 %: no move, however often it looks."""
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=0.5) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            await t.add("c", [count_impl("c", 0.9, probe)])
            for _ in range(400):  # 200 clock seconds: 400 re-evaluations
                tree.tick()
                await step(0.05)
            assert node.assignments == ["b"]
            assert a.mission_control.stats.moved == 0
            stats = _cons(a).stats
            assert stats.auctions > 100  # it did look, every time
            assert stats.awarded == 1
            await tree.shutdown()


async def test_nobody_able_to_take_it_says_why_robot_by_robot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy="consensus") as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", lambda _inputs: None, probe)])
            await t.add("c", [count_impl("c", 1.0, probe)])
            await t.converged()
            task = AssignmentTask(
                ExecutionId("a", "root/count", 1),
                COUNT.name,
                COUNT.identity,
                {"x": 1},
                frozenset({"b"}),
                2.0,
            )
            out = await _cons(a).assign(task)
            assert isinstance(out, Unassigned)
            assert "cannot execute" in out.reasons["b"]
            assert _cons(a).stats.early_closes == 1  # the team agreed that nobody can
            assert not _cons(a).core.tasks()  # withdrawn from the team


async def test_a_hostile_peer_is_held_to_its_own_word_and_to_the_bounds() -> None:
    """m floods task ids and claims in another robot's name: the claim is refused, the
    tasks beyond the bound are dropped and counted, and the mission still runs."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy="consensus") as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            async with silent_member(t.net, "m", [], t.clock) as m:
                await until(lambda: "m" in _cons(a).core.members, "m to be a member")
                flood = [
                    OpenTask(ExecutionId("m", "n", i), "Count", COUNT.identity, {}, ["a"])
                    for i in range(1000)
                ]
                to = Address("a", ConsensusAssigner.PATH)
                m.tell(to, ConsensusTasks("m", 1, flood))
                m.tell(to, ConsensusTasks("b", 2, flood[:1]))  # in b's name
                m.tell(to, ConsensusClaim("b", 1, 9, None, 0.0, "", []))  # in b's name
                stats = _cons(a).stats
                await until(lambda: stats.refused == 2, "the claims in b's name refused")
                assert stats.dropped == 1000 - 256
                assert len(_cons(a).core.tasks()) == 256
                node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                state = await tick_until(tree, lambda s: s is not State.RUNNING)
                assert state is State.SUCCEEDED
                assert node.assignments == ["b"]
                await tree.shutdown()


async def test_a_robot_joining_mid_consensus_hears_the_open_tasks_at_once() -> None:
    """The team cannot agree before the newcomer has merged every origin's open tasks, so
    it must be sent them when it joins, not only at the next retry (a quarter window)."""
    window = 1000.0
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None, auction_window_s=window) as t:
            a = await t.add("a")
            await t.add("c", [count_impl("c", 5.0, probe)])
            # s could run it but never bids: no agreement, a waits
            async with silent_member(t.net, "s", [count_impl("s", 9.0, probe)], t.clock):
                await until(lambda: "s" in _cons(a).core.members, "s to be a member")
                known = {"c", "s"}
                await until(lambda: a.repository.providers(COUNT.identity) == known, "c, s known")
                node = COUNT.node_type()("count", inputs={"x": 1})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                await tick_until(tree, lambda _s: bool(_cons(a).core.winners()), "a claim")
                joined = t.clock.now()
                b = await t.add("b")
                await until(lambda: bool(_cons(b).core.tasks()), "b to hear a's task")
                assert t.clock.now() - joined < window / 4
                await tree.shutdown()


async def test_a_claim_lost_on_the_way_is_asked_for_again_and_wins() -> None:
    """b's claims to the origin are lost and b's state does not change after: the
    origin's retry must make b say it again, so the task goes to b (the cheapest) on
    agreement, not to c when the window ends."""
    window = 40.0
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None, auction_window_s=window) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 5.0, probe)])
            await t.converged()
            route = t.net._route
            lost: list[ConsensusClaim] = []

            def lossy(src: Any, env: Envelope) -> None:
                msg = env.msg
                if (
                    t.clock.now() < opened + window / 8  # lost until b has settled
                    and src.system_id == "b"
                    and env.recipient.system == "a"
                    and isinstance(msg, ConsensusClaim)
                    and msg.task is not None
                ):
                    lost.append(msg)
                    return
                route(src, env)

            opened = t.clock.now()
            t.net._route = lossy  # type: ignore[method-assign]
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            state = await tick_until(tree, lambda s: s is not State.RUNNING)
            assert lost
            assert state is State.SUCCEEDED
            assert node.assignments == ["b"]
            assert t.clock.now() - opened < window
            assert _cons(a).stats.early_closes == 1
            await tree.shutdown()


async def test_a_robot_that_lost_the_origin_and_took_it_back_is_told_its_tasks() -> None:
    """b falsely declares the origin failed (a's heartbeats to b are lost; a still hears
    b) and so forgets a's open task. When a is back, b's view of a has gone backwards:
    a must tell b its tasks again at once, not at a quarter-window retry."""
    window = 1000.0
    with anyio.fail_after(20):
        probe = Probe()
        async with team(strategy="consensus", reevaluate_s=None, auction_window_s=window) as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            route = t.net._route
            cut = [True]

            def lossy(src: Any, env: Envelope) -> None:
                to_b = src.system_id == "a" and env.recipient.system in ("b", BROADCAST)
                if cut[0] and to_b and isinstance(env.msg, Heartbeat):
                    return
                route(src, env)

            t.net._route = lossy  # type: ignore[method-assign]
            await until(lambda: "a" not in b.team.alive(), "b to declare a failed")
            assert "b" in a.team.alive()
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            # a suspects b now and then (its probes to b are lost) and, waiting for no
            # suspect, may agree meanwhile that nobody takes the task: the task then closes
            # unassigned and opens again later, so its first opening is what is waited for
            opened: list[AuctionRecord] = []
            _cons(a).watch(opened.append)
            await tick_until(tree, lambda _s: bool(opened), "the offer")
            cut[0] = False
            back = t.clock.now()
            state = await tick_until(tree, lambda s: s is not State.RUNNING)
            assert state is State.SUCCEEDED
            assert node.assignments == ["b"]
            assert t.clock.now() - back < window / 4
            await tree.shutdown()


async def test_agreement_waits_for_no_suspected_member() -> None:
    """s could run the task (cheaply) but never speaks, then goes quiet: once a suspects
    it, the team agrees without it and a runs the task, long before the window ends or s
    is declared failed; a task opened while s is suspected never waits for it."""
    with anyio.fail_after(20):
        probe = Probe()
        cfg = {"reevaluate_s": None, "auction_window_s": 1000.0, "failure_timeout_s": 500.0}
        async with team(strategy="consensus", **cfg) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            async with silent_member(
                t.net, "s", [count_impl("s", 0.1, probe)], t.clock, failure_timeout_s=500.0
            ):
                await until(lambda: a.repository.providers(COUNT.identity) == {"a", "s"})
                await until(lambda: "s" in a.team.alive(), "a to know s")
                core = _cons(a).core
                for first in (True, False):
                    node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                    tree = a.mission(ReactiveSequence("root", children=[node]))
                    start = t.clock.now()
                    if first:  # open before the suspicion: it waits for s alone
                        tree.tick()
                        await until(lambda: core.waiting_for() == {"s"}, "a's own claim")
                        t.net.isolate("s")
                    else:  # opened while s is suspected
                        assert "s" in a.team.suspected()
                    status = await tick_until(tree, lambda s: s is not State.RUNNING)
                    assert status is State.SUCCEEDED
                    assert node.assignments == ["a"]
                    assert t.clock.now() - start < 100.0  # neither window nor failure
                    assert "s" in a.team.suspected()  # still a member, suspected
                    assert "s" in core.members
                    await tree.shutdown()
            assert not probe.violations
