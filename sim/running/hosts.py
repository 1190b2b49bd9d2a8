"""Where a scenario's robots live while it runs, and how their crashes are reported.

A host starts, stops, freezes and thaws robots as the scenario says, and keeps every crash
of a robot (its runtime raising, its process dying) in ``errors``: logged with the robot's
name as it happens and reported in the mission result, never dropped. In-process robots
are here; robots in their own OS processes are in :mod:`btcap.sim.running.distributed`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import AsyncExitStack
from typing import Any, Protocol

import anyio
import anyio.abc
import msgspec

from btcap.actors import TimeSource
from btcap.sim.mission.capabilities import RobotSetup, robot_setup
from btcap.sim.mission.scenario import Scenario
from btcap.sim.running.metrics import RobotError
from btcap.sim.world.grid import GridMap
from btcap.sim.world.messages import SIM_MESSAGES
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.protocol import protocol_registry
from btcap.team.settings import AgentConfig
from btcap.transports import InProcessNetwork, MessageRegistry, Transport
from btcap.transports.log import get_logger

__all__ = [
    "SIM_SYSTEM",
    "InProcessHost",
    "RobotHost",
    "agent_config",
    "agent_options",
    "describe",
    "record_error",
    "registry",
]

log = get_logger(__name__)

#: The actor system of the simulation manager (the robots' bodies and the shared store).
SIM_SYSTEM = "sim"


def registry() -> MessageRegistry:
    """Every message of btcap plus the simulation's."""
    reg = protocol_registry()
    reg.register(*SIM_MESSAGES)
    return reg


def agent_options(s: Scenario) -> dict[str, Any]:
    """The scenario's ``agent:`` and ``allocation:`` blocks as AgentConfig keywords (their
    fields are named alike, so a new setting needs no mapping here)."""
    return {**msgspec.structs.asdict(s.agent), **msgspec.structs.asdict(s.allocation)}


def agent_config(s: Scenario) -> AgentConfig:
    return AgentConfig.of(s.agent, s.allocation)


def describe(exc: BaseException) -> str:
    """One line for an exception and the error it wraps (an escalation's real cause)."""
    text = f"{type(exc).__name__}: {exc}"
    cause = exc.__cause__
    return text if cause is None else f"{text} ({type(cause).__name__}: {cause})"


def record_error(
    errors: list[RobotError], time: float, robot: str, error: BaseException | str
) -> None:
    """Log a robot's crash with its name and keep it for the mission result."""
    text = error if isinstance(error, str) else describe(error)
    exc_info = error if isinstance(error, BaseException) else None
    log.error("sim.robot_error", robot=robot, error=text, exc_info=exc_info)
    errors.append(RobotError(time, robot, text))


class RobotHost(Protocol):
    """Where robots live; entered with ``async with`` around the mission.

    ``errors`` holds every crash of a robot so far, at clock time (see
    :func:`record_error`).
    """

    errors: list[RobotError]

    def transport(self, system_id: str) -> Transport: ...

    def start(self, name: str) -> None: ...

    def leave(self, name: str) -> None: ...

    def fail(self, name: str) -> None: ...

    def recover(self, name: str) -> None: ...

    def present(self) -> set[str]: ...

    async def __aenter__(self) -> RobotHost: ...

    async def __aexit__(self, *exc: object) -> None: ...


class InProcessHost:
    """Every robot an :class:`Agent` in this event loop, on one in-process network.

    Each robot's life is a task of the host's task group: a robot that crashes is
    recorded in ``errors`` and the others go on; leaving the ``async with`` stops all.
    """

    def __init__(self, s: Scenario, clock: TimeSource, reg: MessageRegistry, grid: GridMap) -> None:
        self.s = s
        self.clock = clock
        self.reg = reg
        self.grid = grid
        self.net = InProcessNetwork(reg)
        self.cfg = agent_config(s)
        self.models = s.models()
        self.errors: list[RobotError] = []
        self._stack = AsyncExitStack()
        self._tg: anyio.abc.TaskGroup | None = None
        self._stop: dict[str, anyio.Event] = {}
        self._gone: dict[str, anyio.Event] = {}
        self._up: set[str] = set()
        self._lives = 0  # incarnations handed out, on a virtual clock
        #: Told of every robot's agent when it starts; returns what to undo before it stops.
        self.on_agent: Callable[[Agent], Callable[[], None]] | None = None

    async def __aenter__(self) -> InProcessHost:
        self._tg = await self._stack.enter_async_context(anyio.create_task_group())
        return self

    async def __aexit__(self, *exc: object) -> None:
        for ev in self._stop.values():
            ev.set()
        await self._stack.aclose()  # every robot has left
        self._tg = None

    def transport(self, system_id: str) -> Transport:
        return self.net.transport(system_id)

    def start(self, name: str) -> None:
        if self._tg is None:
            raise RuntimeError("InProcessHost: start robots inside `async with host`")
        before = self._gone.get(name)
        stop = self._stop[name] = anyio.Event()
        gone = self._gone[name] = anyio.Event()
        self._tg.start_soon(self._life, name, stop, before, gone, name=f"robot {name}")

    async def _life(
        self, name: str, stop: anyio.Event, before: anyio.Event | None, gone: anyio.Event
    ) -> None:
        try:
            if before is not None:  # a robot that left must be gone before it comes back
                await before.wait()
            setup = self.setup(name)
            agent = Agent(
                name,
                transport=self.net.transport(name),
                clock=self.clock,
                config=self.cfg,
                registry=self.reg,
                implementations=setup.implementations,
                actors=setup.actors,
            )
            if math.isinf(self.clock.speedup):  # lives numbered by the run: the same ids
                self._lives += 1
                agent.team.incarnation = self._lives
            async with agent:
                undo = self.on_agent(agent) if self.on_agent is not None else None
                self._up.add(name)
                try:
                    await stop.wait()
                finally:
                    self._up.discard(name)
                    if undo is not None:
                        undo()
        except Exception as exc:
            record_error(self.errors, self.clock.now(), name, exc)
        finally:
            gone.set()

    def setup(self, name: str) -> RobotSetup:
        """What robot ``name`` brings to its agent, each time it starts."""
        model = next(r.model for r in self.s.robots if r.name == name)
        return robot_setup(name, self.models[model], self.grid, bids=self.s.bids)

    def leave(self, name: str) -> None:
        ev = self._stop.get(name)
        if ev is not None:
            ev.set()

    def fail(self, name: str) -> None:
        # Cut off from the team, not from its own body: the simulation stands in for the
        # robot's hardware, whose word that an operation stopped still reaches it.
        self.net.isolate(name, keep=(SIM_SYSTEM,))
        self._up.discard(name)

    def recover(self, name: str) -> None:
        self.net.heal(name)
        gone = self._gone.get(name)
        if gone is not None and not gone.is_set():  # it did not crash meanwhile
            self._up.add(name)

    def present(self) -> set[str]:
        return set(self._up)
