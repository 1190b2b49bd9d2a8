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
from btcap.team.capabilities.capability import Capability

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


async def until_state(node: Capability, state: State) -> None:
    for _ in range(200):  # each step lets the loop run; the clock jumps when idle
        if node.state is state:
            return
        await asyncio.sleep(0)
    raise AssertionError(f"{node.path}: not {state} but {node.state}")


async def test_a_robot_joining_ticks_the_mission_tree_for_waiting_work() -> None:
    """Nobody can take the task (its retry 1000 s away) until b joins: it is auctioned as
    soon as b's capabilities are known, not at the tree's next period."""
    with anyio.fail_after(20):
        async with team() as t:
            a = await t.add("a")
            node = COUNT.node_type()("count", inputs={"x": 1, "stop": True}, retry_s=1000.0)
            tree = a.mission(Counted(ReactiveSequence("root", children=[node]), clock=t.clock))
            run = asyncio.ensure_future(tree.run(rate_hz=1 / PERIOD_S))
            await until_state(node, State.UNASSIGNED)
            ticks = tree.ticks
            await t.add("b", [count_impl("b", 1.0, Probe())])
            joined = t.clock.now()
            assert await run is State.SUCCEEDED
            assert node.assignments == ["b"]
            # Without the nudge the node waits for the tree's next period (100 s).
            assert t.clock.now() - joined < PERIOD_S / 10
            assert tree.ticks > ticks
            await tree.shutdown()


async def test_a_robot_coming_free_of_others_work_ticks_the_mission_tree() -> None:
    """b runs c's task; a's waits (its retry 1000 s away) until b's heartbeat says it came
    free, then is auctioned at once, not at a's tree's next period."""
    with anyio.fail_after(20):
        async with team() as t:
            a = await t.add("a")
            c = await t.add("c")
            await t.add("b", [count_impl("b", 1.0, Probe())])
            await t.converged()
            theirs = COUNT.node_type()("theirs", inputs={"x": 1})
            c_tree = c.mission(ReactiveSequence("root", children=[theirs]))
            c_run = asyncio.ensure_future(c_tree.run(rate_hz=20.0))
            await until_state(theirs, State.RUNNING)
            mine = COUNT.node_type()("mine", inputs={"x": 2, "stop": True}, retry_s=1000.0)
            tree = a.mission(Counted(ReactiveSequence("root", children=[mine]), clock=t.clock))
            run = asyncio.ensure_future(tree.run(rate_hz=1 / PERIOD_S))
            await until_state(mine, State.UNASSIGNED)
            for _ in range(50):  # b is busy: a's auction found nobody
                if mine._request is None:
                    break
                await asyncio.sleep(0)
            theirs.inputs["stop"] = True
            freed = t.clock.now()
            assert await c_run is State.SUCCEEDED
            assert await run is State.SUCCEEDED
            assert mine.assignments == ["b"]
            assert t.clock.now() - freed < PERIOD_S / 10
            await tree.shutdown()
            await c_tree.shutdown()
