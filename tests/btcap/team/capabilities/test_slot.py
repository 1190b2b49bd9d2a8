"""The remote capability slot: one hosted run at a time, ticked by the robot's own tree,
leaving nothing behind."""

from __future__ import annotations

from typing import Any

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team, tick_until, until
from structlog.testing import capture_logs

from btcap import AlwaysRunning, Leaf, Parallel, ReactiveSequence, State, Tree, TreeError
from btcap.bt.running import nudge
from btcap.team.capabilities.implementation import Implementation, ImplementationRun
from btcap.team.capabilities.slot import RemoteCapabilitySlot
from btcap.team.core.hosting import Hosted
from btcap.team.ids import ExecutionId
from btcap.team.runtime.agent import Agent


def _trees(agent: Agent) -> list[str]:
    """Paths of the tree actors living in the agent's system, besides its host tree."""
    return sorted(
        p
        for p in agent.system._actors
        if p.startswith("tree:") and "/" not in p and p != f"tree:{agent.host.name}"
    )


def test_slot_outside_an_agent_fails_setup() -> None:
    with pytest.raises(TreeError, match="attached to a robot's system"):
        Tree(RemoteCapabilitySlot()).setup()


async def test_remote_run_in_a_slot_leaves_no_trace() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a, b = await t.origin_and_executor(probe)
            slot = b.mission_control.slot
            assert isinstance(slot, RemoteCapabilitySlot)
            node = COUNT.node_type()("count", inputs={"x": 2})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            await tick_until(tree, lambda _s: node.state is State.RUNNING, "running")
            assert slot.current is not None
            assert slot.current.execution == node.execution.id  # type: ignore[union-attr]
            assert len(_trees(b)) == 1  # the run's nodes are actors of b while it runs
            assert slot.state is State.RUNNING  # the slot itself is a service: always running
            node.set_input("stop", True)
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await until(lambda: slot.current is None and not _trees(b), "the run to go")
            assert probe.live("b") == 0
            await tree.shutdown()


async def test_slot_refuses_a_second_run_and_runs_only_once_set_up() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            slot = b.mission_control.slot
            assert slot is not None

            def hosted(i: int) -> Hosted[ImplementationRun]:
                run = count_impl("b", 1.0, probe).instantiate(b.clock)
                e, inputs = ExecutionId("x", "root", i), {"x": 1, "stop": False}
                return Hosted(e, run, inputs, 1.0, 0.0, 1.0)

            first = hosted(1)
            assert slot.load(first) is None
            # News for a node of the run (a ROS goal answered) ticks the robot's tree.
            nudge(first.run.tree)
            assert b.host.alarm.nudged
            assert not first.run.tree.alarm.nudged
            assert slot.load(hosted(2)) == "slot busy with x:root#1"
            slot.unload(ExecutionId("x", "root", 3))  # not the current one: no effect
            assert slot.current is first
            slot.unload(first.execution)
            assert slot.current is None
            await first.run.close()
            # A slot that is not set up (its tree shut down) takes nothing.
            await b.host.shutdown()
            assert slot.load(hosted(4)) == "slot not set up"


async def test_slot_watchers_hear_each_run_taken_up_and_put_down_with_why() -> None:
    """What a monitor records a hosted run from: told at once, never per tick; a watcher
    that raises is logged and the run goes on; an unsubscribed one hears nothing."""
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            b = await t.add("b", [count_impl("b", 1.0, probe)])
            slot = b.mission_control.slot
            assert slot is not None
            heard: list[tuple[str, str | None]] = []

            def broken(h: Hosted[ImplementationRun], why: str | None) -> None:
                raise RuntimeError("an onlooker's bug")

            unwatch = slot.watch(lambda h, why: heard.append((str(h.execution), why)))
            slot.watch(broken)

            def hosted(i: int) -> Hosted[ImplementationRun]:
                run = count_impl("b", 1.0, probe).instantiate(b.clock)
                return Hosted(ExecutionId("x", "root", i), run, {"x": 1}, 1.0, 0.0, 1.0)

            first, second = hosted(1), hosted(2)
            with capture_logs() as logs:
                assert slot.load(first) is None
                slot.unload(first.execution, "cancelled")
            assert heard == [("x:root#1", None), ("x:root#1", "cancelled")]
            assert [e["event"] for e in logs] == ["slot.watcher_failed"] * 2
            unwatch()
            assert slot.load(second) is None
            slot.unload(second.execution)
            assert len(heard) == 2
            await first.run.close()
            await second.run.close()


async def test_a_robot_without_a_slot_runs_only_its_own_capabilities() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            c = Agent(
                "c",
                transport=t.net.transport("c"),
                clock=t.clock,
                implementations=[count_impl("c", 1.0, probe)],
                host=AlwaysRunning("busy"),
            )
            async with c:
                await until(
                    lambda: (
                        a.repository.providers(COUNT.identity) == {"a", "c"}
                        and "c" in a.team.alive()
                    ),
                    "a to know c",
                )
                assert c.mission_control.slot is None
                node = COUNT.node_type()("count", inputs={"x": 1, "stop": True})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                assert node.assignments == ["a"]
                out = a.allocator.outcomes[-1]
                assert out is not None
                assert out.declined["c"] == "no remote capability slot"
                # c itself may still run it locally.
                own = COUNT.node_type()("own", inputs={"x": 1, "stop": True})
                tree2 = c.mission(ReactiveSequence("root2", children=[own]))
                assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                assert own.assignments == ["c"]
                await tree.shutdown()
                await tree2.shutdown()


class Beat(Leaf):
    """The host robot's own work: counts its ticks, never finishes."""

    def __init__(self) -> None:
        super().__init__("beat")
        self.count = 0

    def on_tick(self) -> State:
        self.count += 1
        return State.RUNNING


async def test_host_tree_does_its_own_work_beside_the_slot() -> None:
    with anyio.fail_after(10):
        probe = Probe()
        beat = Beat()
        async with team() as t:
            a = await t.add("a")
            b = Agent(
                "b",
                transport=t.net.transport("b"),
                clock=t.clock,
                implementations=[count_impl("b", 1.0, probe)],
                host=Parallel("host", children=[beat, RemoteCapabilitySlot("slot")]),
            )
            async with b:
                await until(lambda: a.repository.providers(COUNT.identity) == {"b"})
                node = COUNT.node_type()("count", inputs={"x": 3})
                tree = a.mission(ReactiveSequence("root", children=[node]))
                await tick_until(tree, lambda _s: node.outputs["ticks"] == 5, "five remote ticks")
                assert beat.count >= 5  # b's own work went on all along
                # Unticking the host tree pauses the hosted run; the next host tick resumes it.
                b.host.untick()
                assert probe.unticks["b"] == 1
                node.set_input("stop", True)
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                assert node.outputs["y"] == 3
                await tree.shutdown()


async def test_two_slots_in_one_robot_are_refused() -> None:
    with anyio.fail_after(10):
        async with team() as t:
            twice = Agent(
                "b",
                transport=t.net.transport("b"),
                clock=t.clock,
                host=Parallel(
                    "host", children=[RemoteCapabilitySlot("s1"), RemoteCapabilitySlot("s2")]
                ),
            )
            with pytest.raises(TreeError, match="already has a remote capability slot"):
                async with twice:
                    pass


def _broken(robot: str, cost: float, how: str) -> Implementation:
    calls = 0

    def build() -> Any:
        nonlocal calls
        calls += 1
        if how == "raises" and calls > 1:  # the first build only estimates the utility
            raise RuntimeError("sensor driver missing")
        # A node with a required input nobody feeds: setup (validation) fails.
        return ReactiveSequence("s", children=[COUNT.bridge_types()[0](name="in"), _Needs("needs")])

    return Implementation(f"broken-{robot}", COUNT, build, bid=lambda _i: cost)


class _Needs(Leaf):
    INPUTS = {"value": int}

    def on_tick(self) -> State:
        return State.SUCCEEDED


@pytest.mark.parametrize("how", ["raises", "invalid"])
async def test_an_implementation_that_cannot_start_is_declined_not_fatal(how: str) -> None:
    with anyio.fail_after(10):
        probe = Probe()
        bare = COUNT
        async with team() as t:
            a = await t.add("a", [count_impl("a", 5.0, probe)])
            b = await t.add("b", [_broken("b", 1.0, how)])
            await t.converged(bare.identity)
            with capture_logs() as logs:  # (and no slow traceback rendering)
                for i in range(12):  # more than the actors' restart budget
                    node = COUNT.node_type()(f"n{i}", inputs={"x": 1, "stop": True})
                    tree = a.mission(ReactiveSequence(f"root{i}", children=[node]))
                    state = await tick_until(tree, lambda s: s is not State.RUNNING)
                    assert state is State.SUCCEEDED
                    assert node.assignments == ["a"]
                    await tree.shutdown()
            if how == "raises":
                assert any(e["event"] == "mission.build_failed" for e in logs)
            mc = b.mission_control
            assert b.system.lookup("mission_control") is mc
            assert mc._restarts == 0
            assert mc.stats.declined == 12
            assert mc.body.running is None
            assert not mc.host.hosted
            await until(lambda: not _trees(b), "no leftover actors on b")
            # The same holds for b's own capabilities.
            own = COUNT.node_type()("own", inputs={"x": 1, "stop": True})
            tree2 = b.mission(ReactiveSequence("mine", children=[own]))
            with capture_logs() as logs2:
                assert await tick_until(tree2, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            assert own.assignments == ["a"], [e for e in logs2 if e["log_level"] != "debug"]
            await tree2.shutdown()
