"""The team the attack probes strike and the Echo mission it runs, and the wait they use.

``r1`` provides Echo, ``origin`` ticks a mission of one Echo capability in the background
while the attacks go on: what they disturb shows in that mission's outcome.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass

from btcap import ReactiveSequence
from btcap.actors import Actor
from btcap.bt.tree import Tree
from btcap.team.capabilities.capability import Capability
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.transports import ZmqTransport

__all__ = ["EchoMission", "echo_mission", "echo_team", "until"]


@dataclass(frozen=True)
class EchoMission:
    """The Echo node (its state, outputs, inputs to set) and the tree it is ticked in."""

    node: Capability
    tree: Tree


async def until(cond: Callable[[], bool], timeout: float) -> bool:
    """Wait until ``cond()`` holds (True) or ``timeout`` seconds pass (False)."""
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(0.01)
    return True


@contextlib.asynccontextmanager
async def echo_team(
    t1: ZmqTransport,
    to: ZmqTransport,
    config: AgentConfig,
    actors: dict[str, Actor] | None = None,
) -> AsyncIterator[tuple[Agent, Agent]]:
    """``r1`` (Echo's provider, with ``actors`` beside) on ``t1`` and ``origin`` on ``to``,
    started, the origin knowing where r1 is; r1 may not be an Echo provider to it yet."""
    to.add_peer("r1", t1.endpoint)
    r1 = Agent(
        "r1",
        transport=t1,
        registry=t1.codec.registry,
        config=config,
        implementations=implementations("r1"),
        actors=actors,
    )
    origin = Agent("origin", transport=to, registry=to.codec.registry, config=config)
    async with r1, origin:
        yield r1, origin


@contextlib.asynccontextmanager
async def echo_mission(
    origin: Agent, tick_s: float = 0.01, *, shutdown: bool = False
) -> AsyncIterator[EchoMission]:
    """``origin``'s mission of one Echo (input ``value`` 1), ticked every ``tick_s`` until
    the block ends, then shut down if ``shutdown`` (else it stays attached, its states
    readable, until the agent exits). It may not be running yet when the block starts:
    wait for ``node.state`` where that matters."""
    node = ECHO.node_type()("echo", inputs={"value": 1})
    assert isinstance(node, Capability)
    tree = origin.mission(ReactiveSequence("root", children=[node]))
    stop = asyncio.Event()

    async def tick() -> None:
        while not stop.is_set():
            tree.tick()
            await asyncio.sleep(tick_s)

    ticking = asyncio.create_task(tick())
    try:
        yield EchoMission(node, tree)
    finally:
        stop.set()
        await ticking
        if shutdown:
            await tree.shutdown()
