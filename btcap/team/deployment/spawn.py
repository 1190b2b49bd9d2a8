"""Start launch processes (``python -m btcap.team.deployment.launch``) and wait until
their agents listen.

Two handles on the same child process: :class:`AgentProcess` for synchronous code
(:func:`spawn_agent`, :func:`spawn_agents`), and :class:`AsyncAgentProcess` for code
running in an event loop (:func:`open_agent`, :func:`open_agents`), built on anyio's
process and stream API so waiting for a child never blocks the loop. Both read the same
announcements: one JSON line per agent, with its robot and bound endpoint.

The functions that start several processes start a few at a time, each with its ready
deadline from its own start (:mod:`~btcap.team.deployment.startgate` says why).
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType

import anyio
import anyio.abc
import msgspec

from btcap.team.deployment.agentspec import AgentSpec, check_specs
from btcap.team.deployment.startgate import STARTS_AT_ONCE, StartGate, check_at_once

__all__ = [
    "AgentProcess",
    "AsyncAgentProcess",
    "listening",
    "open_agent",
    "open_agents",
    "spawn_agent",
    "spawn_agents",
]

Specs = AgentSpec | Sequence[AgentSpec]


def _specs(spec: Specs) -> list[AgentSpec]:
    specs = [spec] if isinstance(spec, AgentSpec) else list(spec)
    check_specs(specs)
    return specs


def _command(spec: Specs) -> list[str]:
    arg = msgspec.json.encode(spec if isinstance(spec, AgentSpec) else list(spec))
    return [sys.executable, "-m", "btcap.team.deployment.launch", arg.decode()]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def listening(robot: str, endpoint: str) -> str:
    """The line ``btcap agent`` prints once it listens (what :func:`open_agent` waits for)."""
    return f"agent {robot} listening on {endpoint}"


_LISTENING = re.compile(r"agent (\S+) listening on (\S+)")  # what listening() writes


async def _open(argv: list[str], stderr: int | None) -> anyio.abc.Process:
    """The child, in a session of its own (as :class:`AgentProcess`): a Ctrl-C at the
    terminal (SIGINT to the whole foreground process group) reaches the parent only, which
    stops its children cleanly, instead of interrupting every robot half-started. Should
    the parent die, their stdin closes and they leave (:mod:`btcap.team.deployment.supervised`)."""
    return await anyio.open_process(
        argv,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=stderr,
        env=_env(),
        start_new_session=True,
    )


class _Announcements:
    """What a launch process said on stdout so far: the endpoint of each agent that listens
    (a JSON line each, or ``btcap agent``'s own line)."""

    def __init__(self, robots: Sequence[str]) -> None:
        self.robots = list(robots)
        self.endpoints: dict[str, str] = {}
        self._buffer = b""

    def feed(self, chunk: bytes) -> None:
        self._buffer += chunk
        while b"\n" in self._buffer:
            raw, self._buffer = self._buffer.split(b"\n", 1)
            line = raw.decode(errors="replace")
            if (said := _LISTENING.fullmatch(line.strip())) is not None:
                self.endpoints[said[1]] = said[2]
            elif line.startswith("{"):
                info = json.loads(line)
                self.endpoints[str(info["robot"])] = str(info["endpoint"])

    @property
    def complete(self) -> bool:
        return all(r in self.endpoints for r in self.robots)

    def timed_out(self, limit: float) -> TimeoutError:
        missing = ", ".join(r for r in self.robots if r not in self.endpoints)
        return TimeoutError(f"agent {missing} did not listen within {limit:g} s of its start")

    def exited(self, code: int | None) -> RuntimeError:
        robots = ", ".join(self.robots)
        return RuntimeError(
            f"the process of agent {robots} exited (code {code}) before it listened "
            "(its log says why)"
        )


class _Launched:
    """What both process handles tell of the agents they started."""

    def __init__(self, robots: list[str]) -> None:
        self._said = _Announcements(robots)
        self.endpoints = self._said.endpoints

    @property
    def robot(self) -> str:
        return self._said.robots[0]

    @property
    def robots(self) -> list[str]:
        return self._said.robots

    @property
    def endpoint(self) -> str:
        return self.endpoints[self.robot]


class AgentProcess(_Launched):
    """One child process running one or more robots; stop it politely or kill it outright.

    ``endpoints`` maps each robot to its bound endpoint; ``robot`` and ``endpoint`` are
    those of the first (or only) agent. With ``wait=False`` the constructor returns at
    once and :meth:`wait_ready` must be called before the endpoints are known, so many
    processes can start in parallel. Its methods block: from async code use
    :class:`AsyncAgentProcess`.
    """

    def __init__(
        self,
        spec: Specs,
        *,
        timeout: float = 20.0,
        stderr: int | None = None,
        wait: bool = True,
    ) -> None:
        super().__init__([s.robot for s in _specs(spec)])
        self.proc = subprocess.Popen(
            _command(spec),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=stderr,
            env=_env(),
            start_new_session=True,  # see _open
        )
        self._started = time.monotonic()
        self._timeout = timeout
        if wait:
            self.wait_ready()

    def wait_ready(self, timeout: float | None = None) -> dict[str, str]:
        """Block until every agent announced its endpoint; returns ``endpoints``."""
        assert self.proc.stdout is not None
        limit = self._timeout if timeout is None else timeout
        deadline = self._started + limit if timeout is None else time.monotonic() + limit
        fd = self.proc.stdout.fileno()
        while not self._said.complete:
            left = deadline - time.monotonic()
            readable = select.select([fd], [], [], max(0.0, left))[0] if left > 0 else []
            if not readable:
                self.kill()
                raise self._said.timed_out(limit)
            chunk = os.read(fd, 65536)
            if not chunk:
                self.proc.wait()
                self._close_pipes()
                raise self._said.exited(self.proc.returncode)
            self._said.feed(chunk)
        return self.endpoints

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 5.0) -> None:
        """Ask its robots to leave the team cleanly (they say goodbye), then wait."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        self._close_pipes()

    def kill(self) -> None:
        """Die without a word, as a crashed robot would."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self._close_pipes()

    def _close_pipes(self) -> None:
        for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if pipe is not None and not pipe.closed:
                pipe.close()

    def __enter__(self) -> AgentProcess:
        return self

    def __exit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()


def spawn_agent(
    spec: AgentSpec, *, timeout: float = 20.0, stderr: int | None = None
) -> AgentProcess:
    """Start ``spec`` in a child process; its log lines go to our stderr unless redirected."""
    return AgentProcess(spec, timeout=timeout, stderr=stderr)


def spawn_agents(
    groups: Sequence[Specs],
    *,
    timeout: float = 20.0,
    stderr: int | None = None,
    at_once: int = STARTS_AT_ONCE,
) -> list[AgentProcess]:
    """Start one process per group (a spec, or a list of specs sharing a process),
    ``at_once`` at a time, and wait until every agent listens; each has ``timeout``
    seconds from its own start. On failure, the others are killed."""
    check_at_once(at_once)
    procs: list[AgentProcess] = []
    try:
        for i, group in enumerate(groups):
            if i >= at_once:  # a turn: the oldest still starting must listen first
                procs[i - at_once].wait_ready()
            procs.append(AgentProcess(group, timeout=timeout, stderr=stderr, wait=False))
        for p in procs:  # (those that listen already return at once)
            p.wait_ready()
    except BaseException:
        for p in procs:
            p.kill()
        raise
    return procs


class AsyncAgentProcess(_Launched):
    """A launch process driven from an event loop; get one from :func:`open_agent`, or from
    :meth:`spawn` and then :meth:`wait_ready` to signal it while it starts.

    Same properties as :class:`AgentProcess`; waiting, stopping and killing are awaited.
    ``async with`` stops it on exit.
    """

    def __init__(self, robots: list[str], process: anyio.abc.Process) -> None:
        super().__init__(robots)
        self.process = process

    @classmethod
    async def spawn(cls, spec: Specs, *, stderr: int | None = None) -> AsyncAgentProcess:
        """Start the process and return at once; its agents are not listening yet."""
        robots = [s.robot for s in _specs(spec)]
        return cls(robots, await _open(_command(spec), stderr))

    @classmethod
    async def spawn_config(
        cls, config: Path, robot: str, *, stderr: int | None = None, log_level: str = "warning"
    ) -> AsyncAgentProcess:
        """``btcap agent CONFIG`` (the robot the file names) in a child process that leaves
        when our end of its stdin closes; returns at once, as :meth:`spawn`."""
        argv = [sys.executable, "-m", "btcap", "--log-level", log_level, "agent", str(config)]
        return cls([robot], await _open([*argv, "--until-stdin-closes"], stderr))

    @property
    def ready(self) -> bool:
        """Every agent announced its endpoint."""
        return self._said.complete

    async def wait_ready(self, timeout: float = 20.0) -> dict[str, str]:
        """Until every agent announced its endpoint; returns ``endpoints``. TimeoutError, or
        RuntimeError if the process exits first (the process is left as it is)."""
        stdout = self.process.stdout
        assert stdout is not None
        with anyio.move_on_after(timeout):
            while not self._said.complete:
                try:
                    chunk = await stdout.receive()
                except anyio.EndOfStream:
                    raise self._said.exited(await self.process.wait()) from None
                self._said.feed(chunk)
            return self.endpoints
        raise self._said.timed_out(timeout)

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def returncode(self) -> int | None:
        return self.process.returncode

    def alive(self) -> bool:
        return self.process.returncode is None

    def send_signal(self, sig: signal.Signals) -> None:
        if self.alive():
            self.process.send_signal(sig)

    async def wait(self) -> int:
        """Until the process exits; its exit code."""
        return await self.process.wait()

    async def stop(self, timeout: float = 5.0) -> None:
        """Ask its robots to leave the team cleanly (they say goodbye), then wait."""
        with anyio.CancelScope(shield=True):
            if self.alive():
                self.process.terminate()
                with anyio.move_on_after(timeout):
                    await self.process.wait()
            await self.kill()

    async def kill(self) -> None:
        """Die without a word, as a crashed robot would."""
        with anyio.CancelScope(shield=True):
            if self.alive():
                self.process.kill()
            await self.process.aclose()

    async def __aenter__(self) -> AsyncAgentProcess:
        return self

    async def __aexit__(
        self, et: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.stop()


async def open_agent(
    spec: Specs, *, timeout: float = 20.0, stderr: int | None = None
) -> AsyncAgentProcess:
    """Start one process (a spec, or a list of specs sharing it) and wait until every agent
    listens; on failure or cancellation the process is killed."""
    proc = await AsyncAgentProcess.spawn(spec, stderr=stderr)
    try:
        await proc.wait_ready(timeout)
    except BaseException:
        await proc.kill()
        raise
    return proc


async def open_agents(
    groups: Sequence[Specs],
    *,
    timeout: float = 20.0,
    stderr: int | None = None,
    at_once: int = STARTS_AT_ONCE,
) -> list[AsyncAgentProcess]:
    """:func:`open_agent` for each group, ``at_once`` at a time (each has ``timeout``
    seconds from its own start); if any fails, all are killed (the failures are raised
    as an ExceptionGroup)."""
    gate = StartGate(at_once)
    opened: dict[int, AsyncAgentProcess] = {}

    async def one(i: int, group: Specs) -> None:
        async with gate.turn():
            opened[i] = await open_agent(group, timeout=timeout, stderr=stderr)

    try:
        async with anyio.create_task_group() as tg:
            for i, group in enumerate(groups):
                tg.start_soon(one, i, group)
    except BaseException:
        for p in opened.values():
            await p.kill()
        raise
    return [opened[i] for i in range(len(groups))]
