"""Distributed mode: every robot in its own OS process, talking ZeroMQ over tcp loopback.

The simulation manager, the shared store and the operator (holding the mission tree) stay
in this process. A robot that *fails* for a while is frozen (SIGSTOP, then SIGCONT), so
it falls silent exactly as a robot whose computer hangs would; one that *leaves* is
terminated and says goodbye; one that *joins* is started.
"""

from __future__ import annotations

import asyncio
import os
import signal
from collections.abc import Callable
from typing import Any

import msgspec

from btcap.actors import TimeSource
from btcap.sim.capabilities import RobotSetup, robot_setup
from btcap.sim.grid import GridMap
from btcap.sim.metrics import MissionResult
from btcap.sim.runner import Progress, agent_options, run_scenario
from btcap.sim.scenario import Scenario
from btcap.team.launch import AgentProcess, AgentSpec
from btcap.transports import MessageRegistry, Transport, ZmqTransport

__all__ = ["ProcessHost", "robot_factory", "run_distributed"]


def robot_factory(robot: str, scenario: dict[str, Any]) -> RobotSetup:
    """Run in the robot's process: rebuild the map and its implementations."""
    s = msgspec.convert(scenario, Scenario)
    model = next(r.model for r in s.robots if r.name == robot)
    return robot_setup(robot, s.models()[model], s.grid())


class ProcessHost:
    """Robots as child processes; see the module docstring."""

    def __init__(self, s: Scenario, clock: TimeSource, reg: MessageRegistry, grid: GridMap) -> None:
        self.s = s
        self.reg = reg
        self._endpoints: dict[str, str] = {}
        self._procs: dict[str, AgentProcess] = {}
        self.started: dict[str, AgentProcess] = {}  # every process ever started, by robot
        self._frozen: set[str] = set()
        self._pending: set[asyncio.Task[object]] = set()
        self._config = agent_options(s)
        self._scenario = msgspec.to_builtins(s)

    def transport(self, system_id: str) -> Transport:
        t = ZmqTransport(system_id, "tcp://127.0.0.1:*", self.reg, peers=dict(self._endpoints))
        self._endpoints[system_id] = t.endpoint
        return t

    def _later(self, fn: Callable[[], object]) -> None:
        task = asyncio.get_running_loop().create_task(asyncio.to_thread(fn))
        self._pending.add(task)
        task.add_done_callback(self._pending.discard)

    def start(self, name: str) -> None:
        spec = AgentSpec(
            robot=name,
            peers=dict(self._endpoints),
            factory="sim.distributed:robot_factory",
            factory_args={"scenario": self._scenario},
            speedup=self.s.speedup,
            config=self._config,
            registry="sim.runner:registry",
            log_level="error",
        )
        proc = AgentProcess(spec, wait=False)
        self._procs[name] = proc
        self.started[name] = proc
        self._later(proc.wait_ready)

    def leave(self, name: str) -> None:
        proc = self._procs.pop(name, None)
        if proc is not None:
            self._later(proc.stop)

    def _signal(self, name: str, sig: signal.Signals) -> None:
        proc = self._procs.get(name)
        if proc is not None and proc.alive():
            os.kill(proc.pid, sig)

    def fail(self, name: str) -> None:
        self._signal(name, signal.SIGSTOP)
        self._frozen.add(name)

    def recover(self, name: str) -> None:
        self._signal(name, signal.SIGCONT)
        self._frozen.discard(name)

    def present(self) -> set[str]:
        return {n for n, p in self._procs.items() if p.alive()} - self._frozen

    async def aclose(self) -> None:
        for name in list(self._frozen):
            self.recover(name)
        procs = list(self._procs.values())
        self._procs.clear()
        await asyncio.gather(*self._pending, return_exceptions=True)
        await asyncio.gather(*(asyncio.to_thread(p.stop) for p in procs), return_exceptions=True)


async def run_distributed(
    scenario: Scenario, *, on_progress: Callable[[Progress], None] | None = None
) -> MissionResult:
    """Run the scenario with every robot in its own OS process."""
    return await run_scenario(scenario, on_progress=on_progress, host=ProcessHost)
