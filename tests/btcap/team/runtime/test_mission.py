"""Mission control between agents: remote execution, pause/cancel, leases and failures,
joins, preconditions, and hostile or stray protocol messages."""

from __future__ import annotations

import asyncio
import logging
from collections import Counter
from collections.abc import Callable
from typing import Any

import anyio
import pytest
from capfixtures import (
    COUNT,
    Probe,
    Team,
    count_impl,
    silent_member,
    step,
    team,
    tick_until,
    until,
)
from hypothesis import given, settings
from hypothesis import strategies as st
from structlog.testing import capture_logs

from btcap import AlwaysFailure, Leaf, Parallel, ReactiveSequence, State, Tree
from btcap.team.allocation.auction import Assigned, AssignmentTask
from btcap.team.capabilities.capability import Capability, CapabilityInterface
from btcap.team.capabilities.implementation import Implementation, Precondition, Scope
from btcap.team.capabilities.proxies import LocalExecution, RemoteExecution
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Award,
    AwardReply,
    Bid,
    CallForBids,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    NoBid,
    PauseExecution,
    RunState,
)
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.mission import MissionControl


def _count(name: str = "count", **inputs: Any) -> Capability:
    return COUNT.node_type()(name, inputs={"x": 1, **inputs})


def _no_trace(agent: Agent) -> bool:
    mc = agent.mission_control
    slot = mc.slot
    return (
        mc.body.running is None
        and mc.body.queued is None
        and not mc.host.hosted
        and not mc.executor.local_runs
        and not mc.origin.tracked
        and not mc.active
        and (slot is None or slot.current is None)
    )


def _output_is(node: Capability, key: str, want: Any) -> Callable[[State], bool]:
    return lambda _s: node.outputs[key] == want


async def _running_on(tree: Tree, node: Capability, robot: str) -> None:
    await tick_until(
        tree,
        lambda _s: (
            node.state is State.RUNNING
            and node.execution is not None
            and node.execution.robot == robot
        ),
        f"running on {robot}",
    )


# -- remote execution -----------------------------------------------------------------------


async def test_remote_execution_streams_io_both_ways_every_tick() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe, k=2)])
            b = await t.add("b", [count_impl("b", 1.0, probe, k=3)])
            await t.converged()
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            ex = node.execution
            assert isinstance(ex, RemoteExecution)
            assert (
                b.mission_control.body.running == ex.id == next(iter(b.mission_control.host.hosted))
            )
            assert a.mission_control.body.running is None  # the origin's body is free
            assert a.mission_control.origin.tracked == {ex.id: ex.tracked}
            # Change the input on the origin while b runs: b's output follows.
            for x in (4, 7, -3):
                node.set_input("x", x)
                await tick_until(tree, _output_is(node, "y", 3 * x), f"y == {3 * x}")
                assert node.outputs["robot"] == "b"
            ticks = node.outputs["ticks"]
            await tick_until(tree, lambda _s: node.outputs["ticks"] > ticks, "more ticks")
            assert probe.ticks["a"] == 0
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.outputs["y"] == -9
            await until(lambda: _no_trace(a) and _no_trace(b) and probe.live("b") == 0, "no trace")
            assert b.mission_control.stats.hosted == 1
            await tree.shutdown()


@pytest.mark.parametrize("wanted", ["captured", "info", "warning"])
async def test_a_hosted_run_ending_is_logged_at_info_when_info_is_wanted(
    wanted: str, caplog: pytest.LogCaptureFixture
) -> None:
    # The executor checks the level before it logs (a dropped event still cost a structlog
    # call, once a round): info, or structlog without a level filter, still gets it.
    with anyio.fail_after(10):
        probe = Probe()
        caplog.set_level(logging.INFO if wanted == "info" else logging.WARNING, "btcap.team")
        async with team() as t:
            a, _b = await t.origin_and_executor(probe)
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            execution = str(node.execution.id)  # type: ignore[union-attr]
            if wanted == "captured":
                with capture_logs() as events:
                    tree.reset()
                    await until(lambda: probe.live("b") == 0, "the run ended")
                done = [e for e in events if e["event"] == "mission.hosted_done"]
                assert [e["execution"] for e in done] == [execution]
            else:
                tree.reset()
                await until(lambda: probe.live("b") == 0, "the run ended")
                logged = [r for r in caplog.records if "mission.hosted_done" in r.getMessage()]
                assert len(logged) == (1 if wanted == "info" else 0), caplog.text
            await tree.shutdown()


async def test_untick_pauses_the_remote_run_and_ticking_resumes_it() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a, b = await t.origin_and_executor(probe)
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            hosted = next(iter(b.mission_control.host.hosted.values()))
            tree.untick()
            assert node.state is State.PAUSED
            await until(lambda: probe.unticks["b"] == 1 and hosted.paused, "b to pause")
            frozen = probe.ticks["b"]
            assert hosted.state is RunState.PAUSED
            # Paused, not gone: the lease is kept alive without ticks.
            for _ in range(80):  # 0.4 s of wall time = 4 clock s, twice the lease
                await step(0.005)
            assert probe.ticks["b"] == frozen
            assert b.mission_control.host.hosted == {hosted.execution: hosted}
            assert node.execution is not None
            assert node.execution.id == hosted.execution
            # Ticking again resumes the same run.
            await tick_until(tree, lambda _s: probe.ticks["b"] > frozen + 2, "b to resume")
            assert not hosted.paused
            assert node.assignments == ["b"]
            await tree.shutdown()


async def test_untick_while_the_auction_runs_starts_no_work() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(auction_window_s=2.0) as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            # s never answers, so the auction stays open for its whole window.
            async with silent_member(t.net, "s", [count_impl("s", 9.0, probe)], t.clock):
                await until(
                    lambda: (
                        a.repository.providers(COUNT.identity) == {"b", "s"}
                        and len(a.team.alive()) == 3
                    ),
                    "a to know b and s",
                )
                node = _count()
                tree = a.mission(ReactiveSequence("root", children=[node]))
                tree.tick()
                assert node.state is State.UNASSIGNED
                tree.untick()
                assert node.state in {State.PAUSED}
                # Long after the window: nothing was awarded, nothing runs for a paused node.
                start = t.clock.now()
                await until(lambda: t.clock.now() - start > 3.0 and not a.allocator._open)
                assert probe.ticks["b"] == 0
                assert _no_trace(b)
                assert node.execution is None
                # Ticked again, it is auctioned afresh and runs.
                await _running_on(tree, node, "b")
                await tree.shutdown()


async def test_reset_and_shutdown_cancel_the_remote_run_without_trace() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a, b = await t.origin_and_executor(probe)
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            tree.reset()
            assert node.execution is None
            assert node.state is State.IDLE
            await until(lambda: _no_trace(a) and _no_trace(b) and probe.live("b") == 0, "no trace")
            # And again, ended by shutting the mission tree down.
            await _running_on(tree, node, "b")
            assert probe.live("b") == 1
            await tree.shutdown()
            await until(lambda: _no_trace(a) and _no_trace(b) and probe.live("b") == 0, "no trace")
            assert node.assignments == ["b", "b"]


async def test_three_robots_each_capability_to_the_cheapest_free_one() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 2.0, probe)])
            await t.converged()
            n1, n2, n3 = _count("one"), _count("two"), _count("three")
            tree = a.mission(Parallel("root", children=[n1, n2, n3]))
            await tick_until(
                tree, lambda _s: all(n.state is State.RUNNING for n in (n1, n2, n3)), "all running"
            )
            assert sorted(n.assignments[0] for n in (n1, n2, n3)) == ["a", "b", "c"]
            local = [n for n in (n1, n2, n3) if n.assignments == ["a"]]
            assert isinstance(local[0].execution, LocalExecution)
            for n in (n1, n2, n3):
                n.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")


# -- failures and joins ---------------------------------------------------------------------


async def _failover(t: Team, kill: str) -> None:
    probe = Probe()
    a = await t.add("a", [count_impl("a", 5.0, probe)])
    await t.add("b", [count_impl("b", 1.0, probe, k=10)])
    c = await t.add("c", [count_impl("c", 2.0, probe, k=100)])
    await t.converged()
    node = _count(x=1)
    tree = a.mission(ReactiveSequence("root", children=[node]))
    await _running_on(tree, node, "b")
    node.set_input("x", 7)
    await tick_until(tree, lambda _s: node.outputs["y"] == 70, "b to see x=7")
    if kill == "isolate":
        t.net.isolate("b")
    else:
        await t.remove("b")
    await _running_on(tree, node, "c")
    assert node.assignments == ["b", "c"]
    # The new executor started from the latest inputs, not the first ones.
    first = [x for robot, x in probe.first_x.values() if robot == "c"]
    assert first == [7]
    await tick_until(tree, lambda _s: node.outputs["y"] == 700, "c's outputs")
    node.set_input("stop", True)
    assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
    assert a.mission_control.stats.lost == 1
    await tree.shutdown()
    await until(lambda: _no_trace(a) and _no_trace(c), "no trace on a and c")
    if kill == "isolate":
        # The isolated executor gave the run up on its own (its origin went silent).
        b = t["b"]
        await until(lambda: _no_trace(b) and probe.live("b") == 0, "b to drop its run")
    else:
        # The exiting agent shut its run down on the way out.
        assert probe.live("b") == 0


async def test_isolated_executor_lease_lapses_and_the_capability_moves_on() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            await _failover(t, "isolate")


async def test_executor_agent_exiting_mid_task_moves_the_capability_on() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            await _failover(t, "exit")


async def test_lease_lapse_without_membership_failure_reassigns() -> None:
    # The team still sees b (its heartbeats are fine) but nothing b's mission control sends
    # gets through (a one-way partition): only the lease notices.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(failure_timeout_s=1000.0) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            await t.converged()
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            b.mission_control.send = lambda robot, msg: None  # type: ignore[method-assign]
            await _running_on(tree, node, "a")
            assert node.assignments == ["b", "a"]
            assert a.mission_control.stats.lost == 1
            # b gives its run up on its own once the origin stops renewing the lease.
            await until(lambda: _no_trace(b) and probe.live("b") == 0, "b to drop its run")
            await tree.shutdown()


async def test_a_joining_robot_does_not_cancel_healthy_work_but_wins_the_next_auction() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(reevaluate_s=None) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            b = await t.add("b", [count_impl("b", 3.0, probe)])
            await t.converged()
            first = _count("first")
            tree = a.mission(root_node := ReactiveSequence("root", children=[first]))
            await _running_on(tree, first, "b")
            hosted = set(b.mission_control.host.hosted)
            await t.add("c", [count_impl("c", 1.0, probe)])
            await t.converged()
            for _ in range(40):  # keep working for a while with c in the team
                tree.tick()
                await step(0.005)
            assert first.assignments == ["b"]
            assert set(b.mission_control.host.hosted) == hosted
            assert probe.ticks["c"] == 0
            first.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            second = _count("second", stop=True)
            tree2 = a.mission(ReactiveSequence("root2", children=[second]))
            assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert second.assignments == ["c"]
            assert root_node.state is State.SUCCEEDED
            await tree.shutdown()
            await tree2.shutdown()


@pytest.mark.parametrize("executor", ["a", "b"])
@pytest.mark.parametrize(("joiner_cost", "moves"), [(1.0, True), (2.5, False)])
async def test_rebid_on_join_moves_work_only_to_a_robot_cheaper_by_the_margin(
    executor: str, joiner_cost: float, moves: bool
) -> None:
    # The executor won with a bid of 3.0 (run locally by the origin a, or remotely by b);
    # with a 25 % margin a joiner must bid below 2.25 to take the work over.
    with anyio.fail_after(10):
        probe = Probe()
        async with team(rebid_on_join=0.25, reevaluate_s=None) as t:
            a = await t.add("a", [count_impl("a", 3.0 if executor == "a" else 5.0, probe)])
            b = await t.add("b", [count_impl("b", 3.0 if executor == "b" else 5.0, probe)])
            await t.converged()
            node = _count(x=1)
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, executor)
            node.set_input("x", 7)
            await tick_until(tree, _output_is(node, "y", 7), "the executor to see x=7")
            auctions = a.allocator.stats.auctions
            c = await t.add("c", [count_impl("c", joiner_cost, probe, k=100)])
            await t.converged()
            await until(lambda: a.allocator.stats.auctions > auctions, "the offer to c")
            if moves:
                await _running_on(tree, node, "c")
                assert node.assignments == [executor, "c"]
                # c started from the latest inputs, and the old run is gone.
                assert [x for robot, x in probe.first_x.values() if robot == "c"] == [7]
                await tick_until(tree, _output_is(node, "y", 700), "c's outputs")
                old = t[executor]
                await until(lambda: probe.live(executor) == 0, "the old run to shut down")
                assert old.mission_control.body.running is None
                assert (a.mission_control.stats.moved, a.mission_control.stats.lost) == (1, 0)
            else:
                for _ in range(40):  # keep working with c in the team
                    tree.tick()
                    await step(0.005)
                assert node.assignments == [executor]
                assert probe.ticks["c"] == 0
                assert c.mission_control.body.running is None
                assert a.mission_control.stats.moved == 0
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()
            await until(lambda: all(_no_trace(x) for x in (a, b, c)), "no trace anywhere")
            assert sum(probe.live(r) for r in "abc") == 0


async def test_a_reset_while_work_is_being_moved_cancels_the_replacement_too() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(rebid_on_join=0.25, reevaluate_s=None) as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            await t.add("b", [count_impl("b", 3.0, probe)])
            await t.converged()
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            c = await t.add("c", [count_impl("c", 1.0, probe)])
            # Stop ticking: the replacement is made but never adopted by the node.
            await until(lambda: a.mission_control.stats.moved == 1, "the move to c")
            assert c.mission_control.body.running is not None
            tree.reset()
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")
            await tree.shutdown()


def _slow_offers(mc: MissionControl, before: float = 0.0, after: float = 0.0) -> Counter[str]:
    """Stretch the offers of running work (auctions with a reserve) in wall time, as a far
    robot would; counts the offers "started" and "finished"."""
    real = mc.allocator.assign
    offers: Counter[str] = Counter()

    async def assign(task: AssignmentTask) -> Assigned | None:
        if task.holder is None:
            return await real(task)
        offers["started"] += 1
        await step(before)
        won = await real(task)
        await step(after)
        offers["finished"] += 1
        return won

    mc.allocator.assign = assign  # type: ignore[method-assign]
    return offers


async def _moving_team(t: Team, probe: Probe) -> tuple[Agent, Capability, Tree]:
    """a (origin) with its capability running on b (bid 3.0)."""
    a = await t.add("a", [count_impl("a", 5.0, probe)])
    await t.add("b", [count_impl("b", 3.0, probe)])
    await t.converged()
    node = _count()
    tree = a.mission(ReactiveSequence("root", children=[node]))
    await _running_on(tree, node, "b")
    return a, node, tree


async def test_two_robots_joining_at_once_take_the_work_over_only_once() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(rebid_on_join=0.25, reevaluate_s=None) as t:
            a, node, tree = await _moving_team(t, probe)
            offers = _slow_offers(a.mission_control, after=0.05)
            await t.add("c", [count_impl("c", 1.0, probe)])
            await t.add("d", [count_impl("d", 1.0, probe)])
            await until(lambda: offers["started"] >= 1, "an offer to the joiners")
            await tick_until(
                tree,
                lambda _s: node.execution is not None and node.execution.robot in ("c", "d"),
                "the work on a joiner",
            )
            await until(lambda: offers["finished"] == offers["started"], "the offers to end")
            for _ in range(3):  # a later offer finds the work where it is cheapest now
                tree.tick()
                await step(0.005)
            assert len(node.assignments) == 2
            assert node.assignments[0] == "b"
            assert a.mission_control.stats.moved == 1
            for _ in range(20):
                tree.tick()
                await step(0.005)
            busy = [r for r in "bcd" if t[r].mission_control.body.running is not None]
            assert busy == node.assignments[1:]
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")


@pytest.mark.parametrize("when", ["during the offer", "before the hand-over"])
async def test_no_moved_work_runs_for_a_paused_capability(when: str) -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(rebid_on_join=0.25, reevaluate_s=None) as t:
            a, node, tree = await _moving_team(t, probe)
            offers = _slow_offers(a.mission_control, before=0.05)
            c = await t.add("c", [count_impl("c", 1.0, probe)])
            if when == "during the offer":
                await until(lambda: offers["started"] == 1, "the offer to c")
                tree.untick()
                await until(lambda: offers["finished"] == 1, "the offer to end")
            else:
                await until(lambda: a.mission_control.stats.moved == 1, "the move")
                tree.untick()
            await step(0.1)  # a few of c's host ticks (10 ms each)
            assert probe.ticks["c"] == 0
            assert node.state is State.PAUSED
            # Ticking again resumes the work (on c if it was moved) and it completes.
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")
            assert c.mission_control.body.running is None


async def test_a_replacement_lost_before_the_hand_over_leaves_the_work_where_it_was() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(rebid_on_join=0.25, reevaluate_s=None) as t:
            a, node, tree = await _moving_team(t, probe)
            running = node.execution
            await t.add("c", [count_impl("c", 1.0, probe)])
            await until(lambda: a.mission_control.stats.moved == 1, "the move")
            await t.remove("c")  # the joiner goes before the node adopted its work
            await until(lambda: a.mission_control.stats.lost == 1, "c's run lost")
            for _ in range(10):
                tree.tick()
                await step(0.005)
            assert node.execution is running  # b's healthy run goes on
            assert node.assignments == ["b"]
            assert probe.live("b") == 1
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()


# -- queueing work after the current work -------------------------------------------------


@pytest.mark.parametrize("executor", ["a", "b"])
async def test_a_busy_robot_queues_one_more_execution_and_starts_it_when_free(
    executor: str,
) -> None:
    with anyio.fail_after(10):
        probe = Probe()
        other = "b" if executor == "a" else "a"
        async with team(queue_after_current=True, reevaluate_s=None) as t:
            cost = {executor: 1.0, other: 5.0}
            a = await t.add("a", [count_impl("a", cost["a"], probe)])
            await t.add("b", [count_impl("b", cost["b"], probe)])
            await t.converged()
            mc = t[executor].mission_control
            first, second, third = _count("first"), _count("second"), _count("third")
            tree1 = a.mission(ReactiveSequence("root1", children=[first]))
            await _running_on(tree1, first, executor)
            # Busy, the executor bids 1 + 1 = 2 < 5 and takes the second as queued work.
            tree2 = a.mission(ReactiveSequence("root2", children=[second]))
            await tick_until(tree2, lambda _s: second.state is State.ASSIGNED, "second queued")
            assert second.assignments == [executor]
            assert mc.body.queued is not None
            # Its queue is full: the third goes to the other robot.
            tree3 = a.mission(ReactiveSequence("root3", children=[third]))
            await _running_on(tree3, third, other)
            for _ in range(20):  # the queued run waits; it is never ticked beside the first
                tree1.tick()
                tree2.tick()
                assert second.state is State.ASSIGNED
                await step(0.005)
            assert len([r for r, _x in probe.first_x.values() if r == executor]) == 1
            second.set_input("x", 9)
            tree2.tick()
            first.set_input("stop", True)
            assert await tick_until(tree1, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await _running_on(tree2, second, executor)
            assert [x for r, x in probe.first_x.values() if r == executor] == [1, 9]
            assert mc.body.queued is None
            for node, tree in ((second, tree2), (third, tree3)):
                node.set_input("stop", True)
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                await tree.shutdown()
            await tree1.shutdown()
            assert probe.violations == []
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")


@pytest.mark.parametrize("executor", ["a", "b"])
async def test_a_queued_execution_cancelled_before_it_starts_leaves_no_trace(
    executor: str,
) -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(queue_after_current=True) as t:
            other = "b" if executor == "a" else "a"
            cost = {executor: 1.0, other: 5.0}
            a = await t.add("a", [count_impl("a", cost["a"], probe)])
            await t.add("b", [count_impl("b", cost["b"], probe)])
            await t.converged()
            mc = t[executor].mission_control
            first, second = _count("first"), _count("second")
            tree1 = a.mission(ReactiveSequence("root1", children=[first]))
            await _running_on(tree1, first, executor)
            tree2 = a.mission(ReactiveSequence("root2", children=[second]))
            await tick_until(tree2, lambda _s: second.state is State.ASSIGNED, "second queued")
            tree2.untick()  # a queued run pauses without harm
            tree2.reset()
            await until(lambda: mc.body.queued is None, "the queued run to go")
            await tick_until(tree1, lambda _s: first.outputs["ticks"] > 3, "first still runs")
            first.set_input("stop", True)
            assert await tick_until(tree1, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree1.shutdown()
            await tree2.shutdown()
            assert len(probe.first_x) == 1  # the queued run never ran
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")
            assert sum(probe.live(r) for r in "ab") == 0


# -- preconditions ------------------------------------------------------------------------

FIRST = CapabilityInterface(
    "First", inputs={"x": int, "stop": bool}, outputs={"y": int, "ticks": int, "robot": str}
)


async def test_local_precondition_needs_success_on_this_robot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        need = (Precondition("First", Scope.LOCAL),)
        async with team() as t:
            a = await t.add(
                "a", [count_impl("a", 5.0, probe), count_impl("a", 5.0, probe, interface=FIRST)]
            )
            b = await t.add(
                "b",
                [
                    count_impl("b", 1.0, probe, preconditions=need),
                    count_impl("b", 9.0, probe, interface=FIRST),
                ],
            )
            await t.converged()
            n1 = _count("n1", stop=True)
            tree = a.mission(ReactiveSequence("root", children=[n1]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert n1.assignments == ["a"]
            out = a.allocator.outcomes[-1]
            assert out is not None
            assert "precondition First (local) not met" in out.declined["b"]
            # First succeeds on a (cheaper there): b's precondition is still unmet.
            f = FIRST.node_type()("f", inputs={"x": 1, "stop": True})
            tree2 = a.mission(ReactiveSequence("root2", children=[f]))
            assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert f.assignments == ["a"]
            tree.reset()
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert n1.assignments == ["a", "a"]
            # Once First succeeded on b itself, b may bid.
            b.repository.record_success("First")
            tree.reset()
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert n1.assignments == ["a", "a", "b"]
            await tree.shutdown()
            await tree2.shutdown()


async def test_remote_precondition_needs_success_anywhere_in_the_team() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        need = (Precondition("First", Scope.REMOTE),)
        async with team() as t:
            a = await t.add(
                "a", [count_impl("a", 5.0, probe), count_impl("a", 1.0, probe, interface=FIRST)]
            )
            b = await t.add("b", [count_impl("b", 1.0, probe, preconditions=need)])
            await t.converged()
            n1 = _count("n1", stop=True)
            tree = a.mission(ReactiveSequence("root", children=[n1]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert n1.assignments == ["a"]
            f = FIRST.node_type()("f", inputs={"x": 1, "stop": True})
            tree2 = a.mission(ReactiveSequence("root2", children=[f]))
            assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await until(lambda: b.repository.succeeded_anywhere("First"), "b to learn of First")
            tree.reset()
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert n1.assignments == ["a", "b"]
            await tree.shutdown()
            await tree2.shutdown()


async def test_preconditions_are_checked_again_at_award() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        need = (Precondition("First", Scope.REMOTE),)
        async with team() as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", 1.0, probe, preconditions=need)])
            await t.converged()
            b.repository.team["a"].succeeded.append("First")
            mc = b.mission_control
            cfb = CallForBids(AuctionId("a", 9), "Count", COUNT.identity, {"x": 1})
            assert isinstance(mc.executor.bid("a", cfb), Bid)  # remembered: its award is due
            # The member that had done it left before the award came.
            b.repository.team.pop("a")
            execution = ExecutionId("a", "root", 9)
            award = Award(AuctionId("a", 9), execution, "Count", "count-b", {"x": 1}, 1.0)
            reply = await a.system.ref("b/mission_control").ask(award, expect=AwardReply)
            assert not reply.accepted
            assert "precondition First (remote)" in reply.reason
            assert _no_trace(b)


# -- stray and hostile messages -------------------------------------------------------------


async def test_stray_and_foreign_messages_are_ignored_and_the_team_keeps_working() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            x = await t.add("x")  # a peer sending nonsense over the real network
            await t.converged()
            node = _count()
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await _running_on(tree, node, "b")
            real = node.execution
            assert real is not None
            send = x.system.tell
            from btcap.transports import Address

            a_mc, b_mc = Address("a", "mission_control"), Address("b", "mission_control")
            foreign = ExecutionId("x", "root", 1)
            z1, z2 = AuctionId("z", 1), AuctionId("z", 2)
            stray: list[tuple[Address, Any]] = [
                (Address("a", "auctioneer"), Bid(AuctionId("a", 999), "x", 0.0, "count-x")),
                (Address("a", "auctioneer"), NoBid(z1, "x", "")),
                (a_mc, ExecutionStatus(foreign, "x", RunState.SUCCEEDED, {"y": 1})),
                # A real execution, but reported by a robot that does not run it.
                (a_mc, ExecutionStatus(real.id, "x", RunState.SUCCEEDED, {"y": 666})),
                (a_mc, ExecutionStatus(real.id, "x", RunState.LOST, {})),
                (a_mc, KeepAlive("x", [real.id, foreign])),
                (b_mc, ExecutionInputs(foreign, 1, {"x": 5})),
                (b_mc, ExecutionInputs(ExecutionId("", "", 0), 1, {})),
                (b_mc, ExecutionInputs(real.id, 10**6, {"x": "not an int"})),
                (b_mc, PauseExecution(foreign)),
                (b_mc, CancelExecution(foreign, "stray")),
                (b_mc, KeepAlive("x", [foreign])),
                (a_mc, CallForBids(z1, "Nope", "Nope()->()", {})),
                (a_mc, CallForBids(z2, "Count", COUNT.identity, {"x": "bad"})),
                (a_mc, AwardReply(ExecutionId("a", "root", 1), "x", True)),
            ]
            for address, msg in stray:
                send(address, msg)
            # An award for an auction the robot did not bid in is declined; so is one for
            # an implementation it does not have.
            award = Award(AuctionId("x", 1), foreign, "Count", "no-such-impl", {"x": 1}, 1.0)
            reply = await x.system.ref("a/mission_control").ask(award, expect=AwardReply)
            assert not reply.accepted
            assert "we made no bid in auction x#1" in reply.reason
            a.mission_control.executor.bids.bid(AuctionId("x", 1), "Count", a.clock.now())
            reply = await x.system.ref("a/mission_control").ask(award, expect=AwardReply)
            assert not reply.accepted
            assert "no implementation" in reply.reason
            award2 = Award(
                AuctionId("x", 2), ExecutionId("x", "root", 2), "Nope", "count-a", {}, 1.0
            )
            reply = await x.system.ref("a/mission_control").ask(award2, expect=AwardReply)
            assert not reply.accepted
            # The real execution was not disturbed and still finishes on b.
            for _ in range(20):
                tree.tick()
                await step(0.005)
            assert node.execution is real
            assert node.state is State.RUNNING
            assert node.outputs["y"] != 666
            node.set_input("x", 3)
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert node.outputs["y"] == 3
            assert node.assignments == ["b"]
            for agent in (a, b):
                mc = agent.mission_control
                assert agent.system.lookup("mission_control") is mc
                assert mc._restarts == 0
                assert agent.allocator._restarts == 0
            await tree.shutdown()
            # And a new capability is still auctioned and run normally.
            again = _count("again", stop=True)
            tree2 = a.mission(ReactiveSequence("root2", children=[again]))
            assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert again.assignments == ["b"]
            await tree2.shutdown()


# -- one execution per robot, one executor per capability ----------------------------------


def _check_exclusive(t: Team, trees: list[Tree], probe: Probe) -> None:
    assert probe.violations == []
    where: dict[str, str] = {}
    for robot, agent in t.agents.items():
        mc = agent.mission_control
        local_nodes = [
            n
            for tree in trees
            if tree.system is agent.system
            for n in tree.nodes()
            if isinstance(n, Capability) and isinstance(n.execution, LocalExecution)
        ]
        # One running; with queueing, one more accepted and waiting.
        held = len(mc.host.hosted) + len(mc.executor.local_runs) + len(local_nodes)
        most = 2 if mc.config.queue_after_current else 1
        assert held <= most, f"{robot} holds {held} executions at once"
        if held:
            assert mc.body.running is not None
        for eid in mc.host.hosted:
            assert eid in (mc.body.running, mc.body.queued)
            assert eid not in where, f"{eid} hosted on {where[eid]} and {robot}"
            where[eid] = robot
    for tree in trees:
        for n in tree.nodes():
            if isinstance(n, Capability) and n.execution is not None:
                ex = n.execution
                assert where.get(ex.id, ex.robot) == ex.robot


async def _storm(
    costs: list[float], durations: list[int], load: list[tuple[int, int]], queue: bool
) -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(queue_after_current=queue) as t:
            robots = [f"r{i}" for i in range(len(costs))]
            for robot, cost, after in zip(robots, costs, durations, strict=True):
                await t.add(robot, [count_impl(robot, cost, probe, after=after)])
            await t.converged()
            trees: list[Tree] = []
            nodes: list[Capability] = []
            for i, (origin, k) in enumerate(load):
                caps = [COUNT.node_type()(f"c{j}", inputs={"x": j}, retry_s=0.2) for j in range(k)]
                nodes += caps
                agent = t[robots[origin % len(robots)]]
                trees.append(agent.mission(Parallel(f"m{i}", children=caps)))
            pending = list(trees)
            for _ in range(2000):
                # A finished Parallel ticked again would start over: tick only the rest.
                pending = [tree for tree in pending if tree.tick() is not State.SUCCEEDED]
                _check_exclusive(t, trees, probe)
                if not pending:
                    break
                await step(0.005)
                _check_exclusive(t, trees, probe)
            assert all(n.state is State.SUCCEEDED for n in nodes)
            # (A loaded machine may stall long enough for a lease to lapse: then a
            # capability is re-assigned, which is fine; it must still succeed once.)
            for tree in trees:
                await tree.shutdown()
            await until(lambda: all(_no_trace(x) for x in t.agents.values()), "no trace")
            assert probe.violations == []


@settings(max_examples=20, deadline=None)
@given(
    costs=st.lists(st.sampled_from([0.5, 1.0, 2.0]), min_size=2, max_size=3),
    durations=st.lists(st.integers(1, 4), min_size=3, max_size=3),
    load=st.lists(st.tuples(st.integers(0, 2), st.integers(1, 3)), min_size=1, max_size=3),
    queue=st.booleans(),
)
def test_no_robot_ever_runs_two_executions_at_once(
    costs: list[float], durations: list[int], load: list[tuple[int, int]], queue: bool
) -> None:
    asyncio.run(_storm(costs, durations[: len(costs)], load, queue))


# -- results ----------------------------------------------------------------------------------

BARE = CapabilityInterface("Bare")


class _Boom(Leaf):
    def on_tick(self) -> State:
        raise RuntimeError("actuator fault")


@pytest.mark.parametrize("where", ["local", "remote"])
@pytest.mark.parametrize("how", ["fails", "raises"])
async def test_a_failing_implementation_fails_the_capability(where: str, how: str) -> None:
    def build() -> Leaf:
        return AlwaysFailure("nope") if how == "fails" else _Boom("boom")

    with anyio.fail_after(10):
        async with team() as t:
            a = await t.add(
                "a", [Implementation("bare-a", BARE, build)] if where == "local" else []
            )
            b = await t.add(
                "b", [Implementation("bare-b", BARE, build)] if where == "remote" else []
            )
            await t.converged(BARE.identity)
            node = BARE.node_type()("bare")
            tree = a.mission(ReactiveSequence("root", children=[node]))
            with capture_logs():
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.FAILED
            assert node.state is State.FAILED
            assert node.assignments == ["a" if where == "local" else "b"]
            assert "Bare" not in a.repository.succeeded | b.repository.succeeded
            await until(lambda: _no_trace(a) and _no_trace(b), "no trace")
            # The failure is kept until reset, not retried behind the parent's back.
            assert tree.tick() is State.FAILED
            assert len(node.assignments) == 1
            await tree.shutdown()
