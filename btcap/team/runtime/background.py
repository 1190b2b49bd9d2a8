"""An agent in a task of its own, so a team in one process (a test, a simulation) can
start and stop its robots in any order: an actor system holds a task group, and systems
entered in one task must leave it in reverse order."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

from btcap.team.runtime.agent import Agent

__all__ = ["Background", "start_in_background"]


@dataclass(slots=True)
class Background:
    """A running agent and the task it lives in."""

    agent: Agent
    task: asyncio.Task[None]
    _stop: asyncio.Event

    async def stop(self) -> None:
        """Leave the team as the agent's ``async with`` does, and wait until it has."""
        self._stop.set()
        await self.task


async def start_in_background(agent: Agent, *, name: str | None = None) -> Background:
    """Enter ``agent`` in a new task; return once it is up, raising what it raised on
    entry (a bad transport, a port in use)."""
    ready, stop = asyncio.Event(), asyncio.Event()

    async def life() -> None:
        async with agent:
            ready.set()
            await stop.wait()

    task = asyncio.get_running_loop().create_task(life(), name=name or f"agent {agent.robot}")
    waiter = asyncio.ensure_future(ready.wait())
    await asyncio.wait((task, waiter), return_when=asyncio.FIRST_COMPLETED)
    waiter.cancel()
    if task.done():
        task.result()
    return Background(agent, task, stop)
