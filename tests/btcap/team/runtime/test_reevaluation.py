"""Running work is re-evaluated: it moves to a clearly cheaper robot, never back and forth
between near-equal ones, and the hand-over leaves no gap and no double run."""

from __future__ import annotations

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, step, team, tick_until, until

from btcap import Parallel, ReactiveSequence, State
from btcap.team.messages import CostChanged


@pytest.mark.parametrize("strategy", ["auction", "sequential", "consensus"])
async def test_work_moves_to_a_robot_that_comes_free_and_is_clearly_cheaper(strategy: str) -> None:
    """Whatever the strategy: the holder's bid counts the margin lower, c beats it clearly
    once free, and the hand-over never runs the task twice."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team(strategy=strategy, reevaluate_s=1000.0) as t:  # only news here
            a = await t.add("a")
            await t.add("b", [count_impl("b", 5.0, probe)])
            await t.add("c", [count_impl("c", 1.0, probe)])
            await t.converged()
            first = COUNT.node_type()("first", inputs={"x": 1})
            second = COUNT.node_type()("second", inputs={"x": 2})
            tree = a.mission(Parallel("both", children=[first, second]))
            await tick_until(
                tree, lambda _s: first.state is second.state is State.RUNNING, "both running"
            )
            assert {first.assignments[0], second.assignments[0]} == {"b", "c"}
            on_b = first if first.assignments[0] == "b" else second
            on_c = second if on_b is first else first
            on_c.set_input("stop", True)  # c finishes, comes free: news
            await tick_until(tree, lambda _s: on_b.assignments[-1] == "c", "the move to c")
            assert on_b.assignments == ["b", "c"]
            assert a.mission_control.stats.moved == 1
            # The run continues on c from the latest inputs; b no longer runs it.
            on_b.set_input("x", 7)
            await tick_until(tree, lambda _s: on_b.outputs["y"] == 7, "c's outputs")
            await until(lambda: probe.live("b") == 0, "b's run to be shut down")
            assert not probe.violations
            await tree.shutdown()


async def test_near_equal_robots_never_pass_the_work_back_and_forth() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team(reevaluate_s=0.5) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            await t.add("c", [count_impl("c", 1.05, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            for _ in range(400):  # 200 clock seconds: 400 re-evaluations
                tree.tick()
                await step(0.05)
            assert node.assignments == ["b"]
            assert a.mission_control.stats.moved == 0
            assert a.allocator.stats.auctions > 100  # it did look, every time
            await tree.shutdown()


async def test_without_reevaluation_running_work_stays_where_it_is() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(reevaluate_s=None) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 5.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            await t.add("c", [count_impl("c", 1.0, probe)])
            await t.converged()
            for _ in range(100):
                tree.tick()
                await step(0.05)
            assert node.assignments == ["b"]
            await tree.shutdown()


async def test_work_moves_home_when_the_origin_robot_comes_free_and_is_cheaper() -> None:
    with anyio.fail_after(30):
        probe = Probe()
        async with team(reevaluate_s=1.0) as t:
            a = await t.add(
                "a", [count_impl("a", lambda i: 1.0 if i["x"] == 1 else 2.0, probe, after=20)]
            )
            await t.add("b", [count_impl("b", 10.0, probe)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 1})
            n2 = COUNT.node_type()("n2", inputs={"x": 2})
            tree = a.mission(Parallel("both", children=[n1, n2]))
            await tick_until(tree, lambda _s: n1.state is State.SUCCEEDED, "n1 done on a")
            await tick_until(tree, lambda _s: n2.assignments[-1:] == ["a"], "n2 moved home")
            assert n2.assignments == ["b", "a"]
            await until(lambda: probe.live("b") == 0, "b's run shut down")
            assert not probe.violations
            await tree.shutdown()


async def test_a_rising_estimate_of_the_running_robot_is_news_at_once() -> None:
    """b's estimate follows the input x; when x jumps, b reports it (CostChanged) with its
    next keep-alive and the work moves to c, long before the 1000 s period."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team(reevaluate_s=1000.0) as t:
            a = await t.add("a")
            b = await t.add("b", [count_impl("b", lambda inputs: float(inputs["x"]), probe)])
            await t.add("c", [count_impl("c", 10.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            assert node.assignments == ["b"]
            node.set_input("x", 5)  # still cheaper than c: no news worth a move
            for _ in range(20):
                tree.tick()
                await step(0.05)
            assert node.assignments == ["b"]
            node.set_input("x", 50)
            t0 = t.clock.now()
            await tick_until(tree, lambda _s: node.assignments[-1] == "c", "the move to c")
            assert t.clock.now() - t0 < 5 * b.config.keepalive_s + 1.0
            assert a.mission_control.stats.moved == 1
            await until(lambda: probe.live("b") == 0, "b's run to be shut down")
            assert not probe.violations
            await tree.shutdown()


async def test_a_rising_estimate_never_moves_the_work_of_an_origin_that_never_moves() -> None:
    """a runs with ``reevaluate_s=None`` (never moved); its executor b, configured to
    re-evaluate, still reports its rise: the report is noted but moves nothing."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team(reevaluate_s=1000.0) as t:
            a = await t.add("a", reevaluate_s=None)
            await t.add("b", [count_impl("b", lambda inputs: float(inputs["x"]), probe)])
            await t.add("c", [count_impl("c", 10.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            for _ in range(20):  # b's first estimates: its baseline
                tree.tick()
                await step(0.05)
            node.set_input("x", 50)
            ex = node.execution
            assert ex is not None
            await tick_until(tree, lambda _s: ex.cost == 50.0, "b's report")
            for _ in range(40):
                tree.tick()
                await step(0.05)
            assert node.assignments == ["b"]
            assert a.mission_control.stats.moved == 0
            assert not probe.violations
            await tree.shutdown()


async def test_a_cost_report_from_another_robot_than_the_executor_is_refused() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team(reevaluate_s=1000.0) as t:
            a = await t.add("a")
            await t.add("b", [count_impl("b", 1.0, probe)])
            c = await t.add("c", [count_impl("c", 10.0, probe)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            assert node.execution is not None
            refused = a.mission_control.stats.refused
            c.system.tell(a.mission_control.address, CostChanged(node.execution.id, 1e9))
            await until(lambda: a.mission_control.stats.refused == refused + 1, "refused")
            assert node.execution.cost == 1.0
            await tree.shutdown()
