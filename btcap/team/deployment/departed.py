"""Robots that failed or left lately, as the team remembers them (``btcap team status``).

An observer comes after the fact, so it asks every robot what it saw
(:class:`~btcap.team.membership.departures.DepartureLog`) and merges the answers: one
line per robot and life, dated by whoever saw it go first.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import anyio

from btcap.actors import ActorError, ActorSystem, Address
from btcap.team.membership.departures import DepartureLog
from btcap.team.messages import Departures, DeparturesQuery

__all__ = ["DepartureView", "survey_departures"]


@dataclass(frozen=True, slots=True)
class DepartureView:
    robot: str
    incarnation: int
    #: "failed" or "left".
    how: str
    #: Seconds ago (as the teammate that saw it first counts them).
    age_s: float
    why: str


async def survey_departures(
    system: ActorSystem, robots: Iterable[str], *, timeout_s: float = 1.0, limit: int = 32
) -> list[DepartureView]:
    """Departures the ``robots`` saw, asked from ``system`` (an observer's, or an
    agent's), the most recent first (at most ``limit``); a robot that does not answer
    in ``timeout_s`` adds nothing."""
    seen: list[DepartureView] = []

    async def ask(robot: str) -> None:
        with anyio.move_on_after(timeout_s):
            try:
                reply = await system.ask(Address(robot, DepartureLog.PATH), DeparturesQuery())
            except ActorError:  # an older robot, or gone: it adds nothing
                return
            if isinstance(reply, Departures) and reply.robot == robot:
                seen.extend(
                    DepartureView(d.robot, d.incarnation, d.how, d.age_ms / 1000, d.why[:200])
                    for d in reply.departed[:limit]
                )

    async with anyio.create_task_group() as tg:
        for robot in sorted(set(robots)):
            tg.start_soon(ask, robot)
    first: dict[tuple[str, int, str], DepartureView] = {}
    for d in seen:
        key = (d.robot, d.incarnation, d.how)
        if key not in first or d.age_s > first[key].age_s:
            first[key] = d
    return sorted(first.values(), key=lambda d: d.age_s)[:limit]
