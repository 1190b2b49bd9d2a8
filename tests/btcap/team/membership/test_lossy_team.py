"""Whole agents (membership actor, repository, mission control) on a lossy network with
the default settings: nobody is failed who is alive, and a robot cut off is failed by
every other within the stated bound."""

from __future__ import annotations

import random
from collections.abc import Callable
from contextlib import AsyncExitStack

import anyio

from btcap.actors import ManualClock
from btcap.team.core.members import TeamEvent
from btcap.team.core.swim import SwimParams
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork
from btcap.transports.codec import Envelope

DEFAULTS = AgentConfig()
PARAMS = SwimParams(DEFAULTS.heartbeat_s, DEFAULTS.failure_timeout_s)


async def test_a_lossy_team_with_the_defaults_keeps_the_living_and_fails_the_dead() -> None:
    size, loss = 12, 0.05  # five times the loss the bench uses
    rng = random.Random(3)
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry())
    names = [f"r{i:02d}" for i in range(size)]
    failed: list[tuple[str, str, float]] = []

    def lossy(send: Callable[[Envelope], None]) -> Callable[[Envelope], None]:
        def sent(env: Envelope) -> None:
            if rng.random() >= loss:
                send(env)

        return sent

    def note(me: str) -> Callable[[TeamEvent, str], None]:
        def seen(event: TeamEvent, robot: str) -> None:
            if event is TeamEvent.FAILED:
                failed.append((me, robot, clock.now()))

        return seen

    with anyio.fail_after(60):
        async with clock.autojump(), AsyncExitStack() as stack:
            agents = []
            for name in names:
                transport = net.transport(name)
                transport.send = lossy(transport.send)  # type: ignore[method-assign]
                agent = await stack.enter_async_context(
                    Agent(name, transport=transport, clock=clock, config=DEFAULTS)
                )
                agent.team.subscribe(note(name))
                agents.append(agent)
            await clock.sleep(60.0)
            assert failed == []
            assert all(a.team.alive() == set(names) for a in agents)
            net.isolate("r05")
            cut = clock.now()
            await clock.sleep(2 * PARAMS.detection_bound_s(size))
            seen = {me: t - cut for me, robot, t in failed if robot == "r05" and me != "r05"}
            assert set(seen) == set(names) - {"r05"}
            assert max(seen.values()) <= PARAMS.detection_bound_s(size)
            # r05 is alone now: it fails the others; nobody else fails anybody.
            assert {robot for me, robot, _ in failed if me != "r05"} == {"r05"}
