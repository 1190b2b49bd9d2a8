"""News from mission control ticks the mission tree: a capability node's assignment and
its run's result, learnt by message, are acted on at once, not a tick period later.

The trees here tick once per 100 clock seconds on the team's virtual clock: a
capability that finishes within one period was carried by nudges alone."""

from __future__ import annotations

import asyncio

import anyio
from capfixtures import COUNT, Probe, count_impl, team

from btcap import ReactiveSequence, State, Tree
from btcap.bt.running import nudge

PERIOD_S = 100.0


class Counted(Tree):
    """A tree that counts its ticks."""

    ticks = 0

    def tick(self) -> State:
        self.ticks += 1
        return super().tick()


async def test_a_remote_result_ticks_the_mission_tree_at_once() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team() as t:
            a = await t.add("a")
            # b's own tree ticks as rarely: its slot too runs the work on news alone (the
            # run loaded, its lease started by a renewal, its inputs come).
            await t.add("b", [count_impl("b", 1.0, probe, after=1)], tick_hz=1 / PERIOD_S)
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 3})
            tree = a.mission(Counted(ReactiveSequence("root", children=[node]), clock=t.clock))
            start = t.clock.now()
            assert await tree.run(rate_hz=1 / PERIOD_S) is State.SUCCEEDED
            # Auctioned, assigned, inputs sent, run on b, result back: no tree waited for
            # its period (on virtual time all of it takes no time at all; 100 s without
            # the nudges of either tree).
            assert t.clock.now() - start < 1.0
            assert node.assignments == ["b"]
            assert node.outputs["y"] == 3
            # A tick per piece of news (auctioned, assigned, each report that changed the
            # run's state), not one per tick of b's tree.
            assert tree.ticks <= 6, tree.ticks
            await tree.shutdown()


async def test_a_local_run_starts_at_once_and_its_news_ticks_the_mission_tree() -> None:
    with anyio.fail_after(20):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 1.0, probe, after=2)])
            await t.converged()
            node = COUNT.node_type()("count", inputs={"x": 2})
            tree = a.mission(Counted(ReactiveSequence("root", children=[node]), clock=t.clock))
            start = t.clock.now()
            run = asyncio.ensure_future(tree.run(rate_hz=1 / PERIOD_S))
            for _ in range(200):  # each step lets the loop run; the clock jumps when idle
                if node.state is State.RUNNING:
                    break
                await asyncio.sleep(0)
            assert node.state is State.RUNNING
            assert t.clock.now() - start < 1.0
            ticks = tree.ticks
            # News for a node of the run (a ROS goal answered) ticks the mission tree.
            ex = node.execution
            assert ex is not None
            nudge(ex.run.tree)  # type: ignore[attr-defined]
            assert await run is State.SUCCEEDED
            assert t.clock.now() - start < 1.0
            assert tree.ticks == ticks + 1
            assert node.assignments == ["a"]
            await tree.shutdown()
