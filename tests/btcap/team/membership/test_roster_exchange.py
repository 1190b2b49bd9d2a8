"""A team starting as the auction bench starts one (the origin told the endpoints of 50
robots, the robots told nobody's), on the virtual clock without sockets: every robot
learns the whole team from welcomes and answers to its roster requests, and no roster
is refused (a member owes its welcome and an answer to each request at once: taking one
roster per member refused the others, with a warning each)."""

from __future__ import annotations

from contextlib import AsyncExitStack

import anyio
import msgspec
from anyio.abc import TaskStatus

from btcap.actors import ManualClock
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import BROADCAST, Address, InProcessNetwork
from btcap.transports.base import Deliver, Transport
from btcap.transports.codec import Envelope

CONFIG = AgentConfig(heartbeat_s=1.0, failure_timeout_s=5.0)


class Dialling(Transport):
    """An in-process port that reaches only the robots it was told of (its seeds, then
    rosters' contacts) or heard from, as a ZeroMQ transport does: a robot news names
    that it cannot reach is asked about."""

    def __init__(self, net: InProcessNetwork, name: str, seeds: set[str]) -> None:
        self.inner = net.transport(name)
        self.system_id = name
        self.stats = self.inner.stats
        self.known = set(seeds)

    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        def heard(env: Envelope) -> None:
            self.known.add(env.sender.system)
            deliver(env)

        await self.inner.serve(heard, task_status=task_status)

    def send(self, env: Envelope) -> None:
        if env.recipient.system != BROADCAST:
            self.inner.send(env)
            return
        for peer in sorted(self.peers()):
            to = Address(peer, env.recipient.path)
            self.inner.send(msgspec.structs.replace(env, recipient=to))

    def peers(self) -> frozenset[str]:
        return frozenset(self.known) & self.inner.peers()

    def endpoint_of(self, system_id: str) -> str | None:
        known = system_id == self.system_id or system_id in self.known
        return f"inproc://{system_id}" if known else None

    def introduce(self, system_id: str, endpoint: str) -> bool:
        self.known.add(system_id)
        return system_id in self.peers()


async def test_a_starting_team_learns_itself_with_no_roster_refused() -> None:
    """Rosters carry endpoints here (``inproc://NAME``), as over ZeroMQ; the in-process
    network's own ports reach everyone and name no endpoint, so no roster is asked for."""
    clock = ManualClock()
    net = InProcessNetwork(protocol_registry())
    names = [f"b{i:02d}" for i in range(50)]
    everyone = frozenset(["origin", *names])
    with anyio.fail_after(60):
        async with clock.autojump(), AsyncExitStack() as stack:
            agents = [
                await stack.enter_async_context(
                    Agent(name, transport=Dialling(net, name, set()), clock=clock, config=CONFIG)
                )
                for name in names
            ]
            origin = Dialling(net, "origin", set(names))
            agents.append(
                await stack.enter_async_context(
                    Agent("origin", transport=origin, clock=clock, config=CONFIG)
                )
            )
            await clock.sleep(20.0)
            # A latecomer told of one robot only: its welcome and its answers both come.
            late = Dialling(net, "late", {"b00"})
            agents.append(
                await stack.enter_async_context(
                    Agent("late", transport=late, clock=clock, config=CONFIG)
                )
            )
            everyone |= {"late"}
            await clock.sleep(10.0)
            assert {a.team.robot: a.team.alive() for a in agents} == dict.fromkeys(
                everyone, everyone
            )
            assert {a.team.robot: a.team.refused for a in agents} == dict.fromkeys(everyone, 0)
