"""Leases are clock seconds, so the fence that keeps one task on one robot holds only if
the robots' clocks run at the same rate (within the stated drift). A robot whose clock
runs at another speed-up than the auctioneer's does not bid (nor take an award), saying
why, instead of running work that could still act after the origin gave it up and
re-assigned it; the origin's user hears it as a capability nobody can take. Alike with
consensus allocation: such a robot claims none of the origin's tasks, saying why, rather
than winning one and declining its award (a round per task wasted)."""

from __future__ import annotations

import contextlib
import warnings

import anyio
import pytest
from capfixtures import COUNT, Probe, config, count_impl
from structlog.testing import capture_logs

from btcap import ReactiveSequence, UnassignableWarning
from btcap.actors import Clock
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.background import start_in_background
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

STRATEGIES = pytest.mark.parametrize("strategy", ["auction", "consensus"])


async def _team_at(
    speedups: dict[str, float], probe: Probe, strategy: str = "auction"
) -> contextlib.AsyncExitStack:
    """Robots (only "b" implements COUNT), each on its own clock."""
    net = InProcessNetwork(protocol_registry())
    stack = contextlib.AsyncExitStack()
    for robot, speedup in speedups.items():
        agent = Agent(
            robot,
            transport=net.transport(robot),
            clock=Clock(speedup=speedup),
            implementations=[count_impl("b", 1.0, probe)] if robot == "b" else [],
            config=config(strategy=strategy),
        )
        life = await start_in_background(agent)
        stack.push_async_callback(life.stop)
        stack.agents = getattr(stack, "agents", {})  # type: ignore[attr-defined]
        stack.agents[robot] = agent  # type: ignore[attr-defined]
    return stack


async def _converged(a: Agent, b: Agent) -> None:
    for _ in range(2000):  # (the test's fail_after bounds it)
        if b.robot in a.team.alive() and a.repository.providers(COUNT.identity):
            return
        await anyio.sleep(0.01)


def _slower_b_told(caught: list[warnings.WarningMessage]) -> bool:
    return any(
        issubclass(w.category, UnassignableWarning) and "clock speed-up 5 here" in str(w.message)
        for w in caught
    )


@STRATEGIES
async def test_a_robot_on_a_clock_of_another_speedup_does_not_bid_and_says_why(
    strategy: str,
) -> None:
    probe = Probe()
    with anyio.fail_after(20), capture_logs() as logs:
        stack = await _team_at({"a": 10.0, "b": 5.0}, probe, strategy)
        async with stack:
            a, b = stack.agents["a"], stack.agents["b"]  # type: ignore[attr-defined]
            await _converged(a, b)
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                while not _slower_b_told(caught):
                    tree.tick()
                    await anyio.sleep(0.01)
            assert node.assignments == []
            assert a.allocator.stats.declined_awards == 0  # b was never offered one
            assert b.mission_control.stats.declined == 0
            assert b.mission_control.stats.hosted == 0
            assert probe.ticks["b"] == 0  # the work never ran on b
            await tree.shutdown()
    told = [e for e in logs if e["event"] == "mission.speedup_differs"]
    assert len(told) == 1  # on b, once for origin a, however many auctions
    assert "timing.speedup" in told[0]["detail"]


@STRATEGIES
async def test_robots_on_clocks_of_one_speedup_work_together(strategy: str) -> None:
    probe = Probe()
    with anyio.fail_after(20):
        stack = await _team_at({"a": 10.0, "b": 10.0}, probe, strategy)
        async with stack:
            a, b = stack.agents["a"], stack.agents["b"]  # type: ignore[attr-defined]
            await _converged(a, b)
            node = COUNT.node_type()("count", inputs={"x": 1})
            tree = a.mission(ReactiveSequence("root", children=[node]))
            while node.assignments != ["b"]:
                tree.tick()
                await anyio.sleep(0.01)
            await tree.shutdown()
