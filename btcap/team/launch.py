"""Run robots as separate OS processes talking ZeroMQ: one or more :class:`Agent` per process.

``python -m btcap.team.launch SPEC_JSON`` runs the agent described by an :class:`AgentSpec`
(a JSON object), or several agents in one process (a JSON array of specs, each with its
own actor system, transport and port), until stdin closes or it is terminated. For every
agent, once it listens, the process prints one stdout line: a JSON object with the robot
and its bound endpoint, so a parent knows where to connect. :func:`spawn_agent` and
:func:`spawn_agents` do this from Python and return a handle that can stop or kill the
process (for failure experiments).

Many agents per process keep large teams affordable on small machines (50 bidders need
not be 50 interpreters); they still talk to each other and to everyone else over their
own sockets, exactly as robots in separate processes do.
"""

from __future__ import annotations

import asyncio
import importlib
import json
import os
import select
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from types import TracebackType
from typing import Any

import msgspec

from btcap.actors import Clock, configure_logging
from btcap.team.agent import Agent, AgentConfig
from btcap.team.capability import Implementation
from btcap.team.protocol import protocol_registry
from btcap.transports import ZmqTransport

__all__ = [
    "AgentProcess",
    "AgentSpec",
    "load_factory",
    "run_agent",
    "run_agents",
    "spawn_agent",
    "spawn_agents",
]


class AgentSpec(msgspec.Struct, forbid_unknown_fields=True):
    """Everything needed to start one robot in a child process."""

    robot: str
    bind: str = "tcp://127.0.0.1:*"
    peers: dict[str, str] = {}
    factory: str = ""
    factory_args: dict[str, Any] = {}
    speedup: float = 1.0
    config: dict[str, float | bool | None] = {}
    log_level: str = "warning"
    registry: str = ""


ImplementationFactory = Callable[..., Any]


def load_factory(ref: str) -> ImplementationFactory:
    """Resolve ``"package.module:function"``.

    An implementation factory returns an iterable of implementations, or an object with
    ``implementations`` and ``actors`` (a mapping of path to actor to spawn beside the
    runtime, e.g. a simulated robot's body). A registry factory returns the
    :class:`~transports.MessageRegistry` the robot speaks (default: btcap's protocol).
    """
    module, sep, attr = ref.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"implementation factory {ref!r}: expected 'package.module:function'")
    try:
        fn = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"implementation factory {ref!r}: {exc}") from None
    if not callable(fn):
        raise ValueError(f"implementation factory {ref!r} is not callable")
    return fn  # type: ignore[no-any-return]


def _check_specs(specs: Sequence[AgentSpec]) -> None:
    if not specs:
        raise ValueError("no agent specs given")
    robots = [s.robot for s in specs]
    if len(set(robots)) != len(robots):
        raise ValueError(f"robot ids must differ within one process: {robots}")


async def run_agent(spec: AgentSpec, *, ready: Callable[[str], None] | None = None) -> None:
    """Run one agent until cancelled; ``ready(endpoint)`` is called once it listens."""
    made = load_factory(spec.factory)(spec.robot, **spec.factory_args) if spec.factory else []
    impls: list[Implementation]
    extra: dict[str, Any] = {}
    if hasattr(made, "implementations"):
        impls = list(made.implementations)
        extra = dict(getattr(made, "actors", {}))
    else:
        impls = list(made)
    registry = load_factory(spec.registry)() if spec.registry else protocol_registry()
    transport = ZmqTransport(spec.robot, spec.bind, registry, peers=dict(spec.peers))
    options: dict[str, Any] = dict(spec.config)  # None only where AgentConfig allows it
    cfg = AgentConfig(**options)
    async with Agent(
        spec.robot,
        transport=transport,
        clock=Clock(spec.speedup),
        implementations=impls,
        config=cfg,
        registry=registry,
        actors=extra,
    ):
        if ready is not None:
            ready(transport.endpoint)
        await asyncio.Event().wait()


async def run_agents(
    specs: Sequence[AgentSpec], *, ready: Callable[[str, str], None] | None = None
) -> None:
    """Run several agents in this event loop until cancelled (or until one of them fails).

    ``ready(robot, endpoint)`` is called for each agent once it listens.
    """
    _check_specs(specs)

    def ready_of(robot: str) -> Callable[[str], None] | None:
        if ready is None:
            return None
        return lambda endpoint: ready(robot, endpoint)

    tasks = [asyncio.ensure_future(run_agent(s, ready=ready_of(s.robot))) for s in specs]
    try:
        await asyncio.gather(*tasks)
    finally:
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


async def _main_async(specs: Sequence[AgentSpec]) -> None:
    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    assert task is not None
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, task.cancel)

    def announce(robot: str, endpoint: str) -> None:
        line = json.dumps({"robot": robot, "endpoint": endpoint, "pid": os.getpid()})
        print(line, flush=True)

    runner = asyncio.ensure_future(run_agents(specs, ready=announce))
    # Stop when the parent closes our stdin (it went away or wants us gone). A stdin that
    # cannot be watched (/dev/null, a file) means: run until terminated.
    if _watchable(sys.stdin):
        reader = asyncio.StreamReader()
        await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
        eof: asyncio.Future[Any] = asyncio.ensure_future(reader.read())
    else:
        eof = loop.create_future()
    try:
        await asyncio.wait((runner, eof), return_when=asyncio.FIRST_COMPLETED)
    finally:
        for t in (runner, eof):
            t.cancel()
        await asyncio.gather(runner, eof, return_exceptions=True)
    if runner.done() and not runner.cancelled() and (exc := runner.exception()) is not None:
        raise exc


def _watchable(stream: Any) -> bool:
    try:
        mode = os.fstat(stream.fileno()).st_mode
    except (OSError, ValueError, AttributeError):
        return False
    return stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode) or (stat.S_ISCHR(mode) and stream.isatty())


def _decode_specs(text: str) -> list[AgentSpec]:
    decoded = msgspec.json.decode(text, type=AgentSpec | list[AgentSpec])
    specs = [decoded] if isinstance(decoded, AgentSpec) else decoded
    _check_specs(specs)
    return specs


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print(
            "usage: python -m btcap.team.launch SPEC_JSON  (one spec object or an array)",
            file=sys.stderr,
        )
        return 2
    try:
        specs = _decode_specs(args[0])
    except msgspec.ValidationError as exc:
        print(f"agent spec: {exc}", file=sys.stderr)
        return 2
    except msgspec.DecodeError as exc:
        print(f"agent spec: not valid JSON ({exc})", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"agent spec: {exc}", file=sys.stderr)
        return 2
    configure_logging(specs[0].log_level)
    robots = ", ".join(s.robot for s in specs)
    try:
        asyncio.run(_main_async(specs))
    except (KeyboardInterrupt, asyncio.CancelledError):
        pass
    except ValueError as exc:
        print(f"agent {robots}: {exc}", file=sys.stderr)
        return 2
    return 0


class AgentProcess:
    """One child process running one or more robots; stop it politely or kill it outright.

    ``endpoints`` maps each robot to its bound endpoint; ``robot`` and ``endpoint`` are
    those of the first (or only) agent. With ``wait=False`` the constructor returns at
    once and :meth:`wait_ready` must be called before the endpoints are known, so many
    processes can start in parallel.
    """

    def __init__(
        self,
        spec: AgentSpec | Sequence[AgentSpec],
        *,
        timeout: float = 20.0,
        stderr: int | None = None,
        wait: bool = True,
    ) -> None:
        self.specs: list[AgentSpec] = [spec] if isinstance(spec, AgentSpec) else list(spec)
        _check_specs(self.specs)
        self.spec = self.specs[0]
        self.endpoints: dict[str, str] = {}
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        arg = msgspec.json.encode(spec if isinstance(spec, AgentSpec) else self.specs)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "btcap.team.launch", arg.decode()],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=stderr,
            env=env,
        )
        self._started = time.monotonic()
        self._timeout = timeout
        self._buffer = b""
        if wait:
            self.wait_ready()

    def wait_ready(self, timeout: float | None = None) -> dict[str, str]:
        """Block until every agent announced its endpoint; returns ``endpoints``."""
        assert self.proc.stdout is not None
        want = {s.robot for s in self.specs}
        limit = self._timeout if timeout is None else timeout
        deadline = self._started + limit if timeout is None else time.monotonic() + limit
        fd = self.proc.stdout.fileno()
        while not want <= self.endpoints.keys():
            while b"\n" in self._buffer:
                line, self._buffer = self._buffer.split(b"\n", 1)
                info = json.loads(line)
                self.endpoints[str(info["robot"])] = str(info["endpoint"])
            if want <= self.endpoints.keys():
                break
            left = deadline - time.monotonic()
            readable = select.select([fd], [], [], max(0.0, left))[0] if left > 0 else []
            if not readable:
                missing = sorted(want - self.endpoints.keys())
                self.kill()
                raise TimeoutError(f"agents {missing} did not start within {limit} s")
            chunk = os.read(fd, 65536)
            if not chunk:
                self.proc.wait()
                code = self.proc.returncode
                self._close_pipes()
                raise RuntimeError(
                    f"agent process {self.robots} exited (code {code}) before it was ready"
                )
            self._buffer += chunk
        return self.endpoints

    @property
    def robot(self) -> str:
        return self.spec.robot

    @property
    def robots(self) -> list[str]:
        return [s.robot for s in self.specs]

    @property
    def endpoint(self) -> str:
        return self.endpoints[self.spec.robot]

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
    groups: Sequence[AgentSpec | Sequence[AgentSpec]],
    *,
    timeout: float = 20.0,
    stderr: int | None = None,
) -> list[AgentProcess]:
    """Start one process per group (a spec, or a list of specs sharing a process), in
    parallel, and wait until every agent listens. On failure, the others are killed."""
    procs: list[AgentProcess] = []
    try:
        for group in groups:
            procs.append(AgentProcess(group, timeout=timeout, stderr=stderr, wait=False))
        for p in procs:
            p.wait_ready()
    except BaseException:
        for p in procs:
            p.kill()
        raise
    return procs


if __name__ == "__main__":
    raise SystemExit(main())
