"""A node paused between an exchange's commit and its adoption: the other task of the
exchange waits behind its old run, so pausing adopts the replacement (paused) at once."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import anyio
from capfixtures import COUNT, Probe, count_impl, step, team, tick_until

from btcap import Parallel, State


def near_one(robot_for_one: bool) -> Callable[[Mapping[str, Any]], float]:
    """A bid 1 for x == 1 (10 otherwise), or the other way round."""
    return lambda i: 1.0 if (i["x"] == 1) == robot_for_one else 10.0


async def test_a_node_paused_before_it_adopts_its_exchange_holds_nobody_up() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team(reevaluate_s=1000.0) as t:  # news only: the rising estimates
            a = await t.add("a")
            await t.add("b", [count_impl("b", near_one(True), probe)])
            await t.add("c", [count_impl("c", near_one(False), probe)])
            await t.converged()
            n1 = COUNT.node_type()("n1", inputs={"x": 2})
            n2 = COUNT.node_type()("n2", inputs={"x": 1})
            tree = a.mission(Parallel("both", children=[n1, n2]))
            await tick_until(tree, lambda _s: n1.state is n2.state is State.RUNNING, "running")
            assert (n1.assignments, n2.assignments) == (["c"], ["b"])
            for _ in range(20):  # a second: the executors' estimates have a baseline
                tree.tick()
                await step()
            # Crossed: each robot now runs the task the other is next to (10 + 10 vs 1 + 1).
            n1.set_input("x", 1)
            n2.set_input("x", 2)
            for _ in range(2000):
                tree.tick()
                await step()
                e1, e2 = n1.execution, n2.execution
                if e1 is not None and e2 is not None and e1.replacement and e2.replacement:
                    break
            else:
                raise AssertionError("no exchange was committed")
            # Committed, not adopted: n2 pauses now; n1 goes on alone.
            n2.untick()
            for _ in range(400):  # 20 clock seconds (10 leases)
                n1.tick()
                await step()
                if n1.outputs["robot"] == "b":
                    break
            else:
                raise AssertionError("n1 waits for the paused n2's old run on b")
            assert n1.assignments == ["c", "b"]
            assert n2.assignments == ["b", "c"]  # adopted as it paused, still paused
            await tick_until(tree, lambda _s: n2.outputs["robot"] == "c", "n2 resumes on c")
            assert not probe.violations
            await tree.shutdown()
