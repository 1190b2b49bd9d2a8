"""Robots that failed or left lately, as the team remembers them (``btcap team status``).

An observer joins after the fact, so it asks every member what it saw
(:class:`~btcap.team.membership.departures.DepartureLog`) and merges the answers: one
line per robot and life, dated by whoever saw it go first.
"""

from __future__ import annotations

from dataclasses import dataclass

import anyio

from btcap.actors import Address
from btcap.team.membership.departures import DepartureLog
from btcap.team.messages import Departures, DeparturesQuery
from btcap.team.runtime.agent import Agent

__all__ = ["DepartureView", "observe_departures"]


@dataclass(frozen=True, slots=True)
class DepartureView:
    robot: str
    incarnation: int
    #: "failed" or "left".
    how: str
    #: Seconds ago (as the teammate that saw it first counts them).
    age_s: float
    why: str


async def observe_departures(
    agent: Agent, *, timeout_s: float = 1.0, limit: int = 32
) -> list[DepartureView]:
    """Departures ``agent`` and its teammates saw, the most recent first (at most
    ``limit``); a member that does not answer in ``timeout_s`` adds nothing."""
    now = agent.clock.now()
    seen = [
        DepartureView(d.robot, d.incarnation, d.how, max(0.0, now - d.at), d.why)
        for d in agent.departures.departures
    ]

    async def ask(robot: str) -> None:
        with anyio.move_on_after(timeout_s):
            reply = await agent.system.ask(Address(robot, DepartureLog.PATH), DeparturesQuery())
            if isinstance(reply, Departures) and reply.robot == robot:
                seen.extend(
                    DepartureView(d.robot, d.incarnation, d.how, d.age_ms / 1000, d.why[:200])
                    for d in reply.departed[:limit]
                )

    async with anyio.create_task_group() as tg:
        for robot in sorted(agent.team.members):
            tg.start_soon(ask, robot)
    first: dict[tuple[str, int, str], DepartureView] = {}
    for d in seen:
        key = (d.robot, d.incarnation, d.how)
        if key not in first or d.age_s > first[key].age_s:
            first[key] = d
    return sorted(first.values(), key=lambda d: d.age_s)[:limit]
