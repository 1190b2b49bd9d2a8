"""Distributed mode: every robot in its own OS process, talking ZeroMQ over tcp loopback.

Each robot is started exactly as on a real host, ``btcap agent CONFIG``, from a
configuration file written for it: its seeds are the robots already running, and a
plugin (:func:`robot_factory`) gives it the scenario's implementations and simulated body.
The simulation manager, the shared store and the operator (holding the mission tree) stay
in this process. A robot that *fails* for a while is frozen (SIGSTOP, then SIGCONT), so
it falls silent exactly as a robot whose computer hangs would; one that *leaves* is
terminated and says goodbye; one that *joins* is started.

Robots start a few at a time (:class:`~btcap.team.deployment.startgate.StartGate`): each
start is CPU work, and fifty at once on two cores made every one of them late. A robot
waiting for its turn is not started at all if it leaves meanwhile; each one's ready
deadline counts from its own start, and one that does not come up is one line in the
result's errors naming it and why.
"""

from __future__ import annotations

import signal
import tempfile
from collections.abc import Awaitable, Callable
from contextlib import AsyncExitStack
from pathlib import Path
from typing import Any

import anyio
import anyio.abc
import msgspec

from btcap.actors import TimeSource
from btcap.sim.mission.capabilities import RobotSetup, robot_setup
from btcap.sim.mission.scenario import Scenario
from btcap.sim.running.hosts import agent_options, record_error
from btcap.sim.running.metrics import MissionResult, RobotError
from btcap.sim.running.runner import Progress, run_scenario
from btcap.sim.world.grid import GridMap
from btcap.team.deployment.agentconfig import Timing
from btcap.team.deployment.spawn import AsyncAgentProcess
from btcap.team.deployment.startgate import STARTS_AT_ONCE, StartGate
from btcap.transports import MessageRegistry, Transport, ZmqTransport
from btcap.transports.log import get_logger

__all__ = ["READY_S", "ProcessHost", "Spawn", "robot_factory", "run_distributed"]

log = get_logger(__name__)

#: Wall seconds a robot's process has to listen, from when its start began.
READY_S = 20.0

#: Starts a robot's process from its configuration file (path, robot), returning at once.
Spawn = Callable[[Path, str], Awaitable[AsyncAgentProcess]]


def robot_factory(robot: str, scenario: dict[str, Any]) -> RobotSetup:
    """Run in the robot's process: rebuild the map and its implementations."""
    s = msgspec.convert(scenario, Scenario)
    model = next(r.model for r in s.robots if r.name == robot)
    return robot_setup(robot, s.models()[model], s.grid(), bids=s.bids)


class ProcessHost:
    """Robots as child processes; see the module docstring.

    Each process is watched by a task of the host's task group: one that does not come
    up, or exits without being asked to, is recorded in ``errors`` (its log lines are on
    our stderr, or in ``stderr`` when given). ``starts_at_once`` processes start at a
    time, each given ``ready_s`` wall seconds from its own start to listen. ``spawn``
    starts a robot's process (default: ``btcap agent FILE``).
    """

    def __init__(
        self,
        s: Scenario,
        clock: TimeSource,
        reg: MessageRegistry,
        grid: GridMap,
        *,
        stderr: int | None = None,
        starts_at_once: int = STARTS_AT_ONCE,
        ready_s: float = READY_S,
        spawn: Spawn | None = None,
    ) -> None:
        self.s = s
        self.clock = clock
        self.reg = reg
        self.errors: list[RobotError] = []
        self.started: dict[str, AsyncAgentProcess] = {}  # every process started, by robot
        self._stderr = stderr
        self.starts = StartGate(starts_at_once)  #: the robots starting now (and at most)
        self.ready_s = ready_s
        self._spawn: Spawn = spawn or self._agent
        self._endpoints: dict[str, str] = {}
        self._procs: dict[str, AsyncAgentProcess] = {}
        self._leaving: set[AsyncAgentProcess] = set()
        self._starting: set[str] = set()  # started, process not created yet
        self._left_early: set[str] = set()  # left before its process existed
        self._frozen: set[str] = set()
        self._config = agent_options(s)
        self._scenario = msgspec.to_builtins(s)
        self._stack = AsyncExitStack()
        self._dir = Path()
        self._tg: anyio.abc.TaskGroup | None = None

    async def __aenter__(self) -> ProcessHost:
        folder = self._stack.enter_context(tempfile.TemporaryDirectory(prefix="btcap-robots-"))
        self._dir = Path(folder)
        self._tg = await self._stack.enter_async_context(anyio.create_task_group())
        return self

    async def __aexit__(self, *exc: object) -> None:
        for name in list(self._frozen):
            self.recover(name)
        for name in list(self._procs):
            self.leave(name)
        if self._tg is not None:  # stops run shielded; robots still starting are killed
            self._tg.cancel_scope.cancel()
        await self._stack.aclose()
        self._tg = None

    def transport(self, system_id: str) -> Transport:
        t = ZmqTransport(system_id, "tcp://127.0.0.1:*", self.reg, peers=dict(self._endpoints))
        self._endpoints[system_id] = t.endpoint
        return t

    def _task(self, fn: Callable[..., Any], *args: Any, name: str) -> None:
        if self._tg is None:
            raise RuntimeError("ProcessHost: start robots inside `async with host`")
        self._tg.start_soon(fn, *args, name=name)

    def start(self, name: str) -> None:
        path = self._dir / f"{name}.json"
        path.write_bytes(msgspec.json.encode(self._config_file(name)))
        if name in self._starting:  # it left and joins again before its process exists:
            self._left_early.discard(name)  # the start under way still starts it (once)
            return
        self._starting.add(name)
        self._left_early.discard(name)
        self._task(self._life, name, path, name=f"robot {name}")

    def _config_file(self, name: str) -> dict[str, Any]:
        """The robot's ``btcap agent`` configuration (:mod:`btcap.team.deployment.agentconfig`)."""
        timing = {k: v for k, v in self._config.items() if k in Timing.__struct_fields__}
        allocation = {k: v for k, v in self._config.items() if k not in timing}
        return {
            "btcap": 1,
            "robot": name,
            "network": {
                "bind": "tcp://127.0.0.1:*",
                "seeds": [{"robot": r, "endpoint": e} for r, e in self._endpoints.items()],
            },
            "timing": {**timing, "speedup": self.s.speedup},
            "allocation": allocation,
            "plugin": {
                "factory": "btcap.sim.running.distributed:robot_factory",
                "args": {"scenario": self._scenario},
                "messages": "btcap.sim.running.hosts:registry",
            },
        }

    async def _agent(self, path: Path, name: str) -> AsyncAgentProcess:
        return await AsyncAgentProcess.spawn_config(
            path, name, stderr=self._stderr, log_level="error"
        )

    async def _life(self, name: str, path: Path) -> None:
        async with self.starts.turn():  # a few at once; the rest wait here
            proc = await self._begin(name, path)
            if proc is None:
                return
            # Known at once, so a robot that leaves or fails while it starts is stopped
            # or frozen.
            self._procs[name] = proc
            self.started[name] = proc
            try:
                await proc.wait_ready(self.ready_s)  # from this robot's start
            except Exception as exc:  # it never came up: exited, or timed out
                if proc not in self._leaving:
                    record_error(self.errors, self.clock.now(), name, _not_started(exc))
                await proc.kill()
            else:
                if name in self._frozen:  # it failed before it was up: down from now on
                    proc.send_signal(signal.SIGSTOP)
                log.info("sim.robot_up", robot=name, pid=proc.pid, endpoint=proc.endpoint)
        code = await proc.wait()
        if self._procs.get(name) is proc:
            del self._procs[name]
        if proc not in self._leaving and proc.ready:
            record_error(self.errors, self.clock.now(), name, f"process exited with code {code}")

    async def _begin(self, name: str, path: Path) -> AsyncAgentProcess | None:
        """The robot's process, created now it has its turn; None if it left meanwhile
        (stopped if it left while the process was being created) or could not be created."""
        try:
            if name in self._left_early:  # it left while waiting for its turn
                self._left_early.discard(name)
                return None
            proc = await self._spawn(path, name)
        except OSError as exc:
            record_error(self.errors, self.clock.now(), name, f"did not start: {exc}")
            return None
        finally:
            self._starting.discard(name)
        if name in self._left_early:  # it left while its process was being created
            self._left_early.discard(name)
            self.started[name] = proc
            self._leaving.add(proc)
            await proc.stop()
            return None
        return proc

    def leave(self, name: str) -> None:
        if name in self._starting:
            self._left_early.add(name)
        proc = self._procs.pop(name, None)
        if proc is not None:
            self._leaving.add(proc)
            self._task(proc.stop, name=f"stop {name}")

    def fail(self, name: str) -> None:
        """Freeze the robot's process; one not up yet (waiting for its turn, or not yet
        listening: frozen then, it would miss its ready deadline) is frozen once it is
        up, unless it recovered meanwhile, so it never works while counted down."""
        if name not in self._procs and name not in self._starting:
            return
        self._frozen.add(name)
        proc = self._procs.get(name)
        if proc is not None and proc.ready:
            proc.send_signal(signal.SIGSTOP)

    def recover(self, name: str) -> None:
        proc = self._procs.get(name)
        if proc is not None:
            proc.send_signal(signal.SIGCONT)
        self._frozen.discard(name)

    def present(self) -> set[str]:
        return {n for n, p in self._procs.items() if p.ready and p.alive()} - self._frozen


def _not_started(exc: Exception) -> str:
    """One line: why a robot's process did not come up."""
    if isinstance(exc, TimeoutError | RuntimeError):
        return f"did not start: {exc}"
    return f"did not start: {type(exc).__name__}: {exc}"


async def run_distributed(
    scenario: Scenario,
    *,
    on_progress: Callable[[Progress], None] | None = None,
    stop: anyio.Event | None = None,
    **options: Any,
) -> MissionResult:
    """Run the scenario with every robot in its own OS process (``options`` as for
    :func:`~btcap.sim.running.runner.run_scenario`)."""
    return await run_scenario(
        scenario, on_progress=on_progress, host=ProcessHost, stop=stop, **options
    )
