"""Run robots as separate OS processes talking ZeroMQ: one :class:`Agent` per process.

``python -m btcap.launch SPEC_JSON`` runs one agent described by an :class:`AgentSpec`
until stdin closes or it is terminated; its first stdout line is a JSON object with the
bound endpoint, so a parent knows where to connect. :func:`spawn_agent` does this from
Python and returns a handle that can stop or kill the robot (for failure experiments).
"""

from __future__ import annotations

import asyncio
import importlib
import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterable, Sequence
from types import TracebackType
from typing import Any

import msgspec

from actors import Clock, configure_logging
from btcap.agent import Agent, AgentConfig
from btcap.capability import Implementation
from btcap.protocol import protocol_registry
from transports import ZmqTransport

__all__ = ["AgentProcess", "AgentSpec", "load_factory", "run_agent", "spawn_agent"]


class AgentSpec(msgspec.Struct, forbid_unknown_fields=True):
    """Everything needed to start one robot in its own process."""

    robot: str
    bind: str = "tcp://127.0.0.1:*"
    peers: dict[str, str] = {}
    factory: str = ""
    factory_args: dict[str, Any] = {}
    speedup: float = 1.0
    config: dict[str, float] = {}
    log_level: str = "warning"


ImplementationFactory = Callable[..., Iterable[Implementation]]


def load_factory(ref: str) -> ImplementationFactory:
    """Resolve ``"package.module:function"``; the function returns implementations."""
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


async def run_agent(spec: AgentSpec, *, ready: Callable[[str], None] | None = None) -> None:
    """Run one agent until cancelled; ``ready(endpoint)`` is called once it listens."""
    impls = list(load_factory(spec.factory)(spec.robot, **spec.factory_args)) if spec.factory else []
    registry = protocol_registry()
    transport = ZmqTransport(spec.robot, spec.bind, registry, peers=dict(spec.peers))
    cfg = AgentConfig(**spec.config)
    async with Agent(
        spec.robot, transport=transport, clock=Clock(spec.speedup), implementations=impls,
        config=cfg, registry=registry,
    ):
        if ready is not None:
            ready(transport.endpoint)
        await asyncio.Event().wait()


async def _main_async(spec: AgentSpec) -> None:
    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    assert task is not None
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, task.cancel)

    def announce(endpoint: str) -> None:
        print(json.dumps({"robot": spec.robot, "endpoint": endpoint, "pid": os.getpid()}), flush=True)

    runner = asyncio.ensure_future(run_agent(spec, ready=announce))
    # Stop when the parent closes our stdin (it went away or wants us gone).
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    eof = asyncio.ensure_future(reader.read())
    try:
        await asyncio.wait((runner, eof), return_when=asyncio.FIRST_COMPLETED)
    finally:
        for t in (runner, eof):
            t.cancel()
        await asyncio.gather(runner, eof, return_exceptions=True)
    if runner.done() and not runner.cancelled() and runner.exception() is not None:
        raise runner.exception()  # type: ignore[misc]


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m btcap.launch SPEC_JSON", file=sys.stderr)
        return 2
    try:
        spec = msgspec.json.decode(args[0], type=AgentSpec)
    except msgspec.ValidationError as exc:
        print(f"agent spec: {exc}", file=sys.stderr)
        return 2
    except msgspec.DecodeError as exc:
        print(f"agent spec: not valid JSON ({exc})", file=sys.stderr)
        return 2
    configure_logging(spec.log_level)
    try:
        asyncio.run(_main_async(spec))
    except (KeyboardInterrupt, asyncio.CancelledError):
        pass
    except ValueError as exc:
        print(f"agent {spec.robot}: {exc}", file=sys.stderr)
        return 2
    return 0


class AgentProcess:
    """A robot running in a child process; stop it politely or kill it outright."""

    def __init__(
        self, spec: AgentSpec, *, timeout: float = 20.0, stderr: int | None = None
    ) -> None:
        self.spec = spec
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "btcap.launch", msgspec.json.encode(spec).decode()],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=stderr,
            env=env,
        )
        self.endpoint = self._await_ready(timeout)

    def _await_ready(self, timeout: float) -> str:
        import selectors

        assert self.proc.stdout is not None
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        try:
            if not sel.select(timeout):
                self.kill()
                raise TimeoutError(f"agent {self.spec.robot} did not start within {timeout} s")
        finally:
            sel.close()
        line = self.proc.stdout.readline()
        if not line:
            self.kill()
            raise RuntimeError(
                f"agent {self.spec.robot} exited (code {self.proc.returncode}) before it was ready"
            )
        info = json.loads(line)
        return str(info["endpoint"])

    @property
    def robot(self) -> str:
        return self.spec.robot

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 5.0) -> None:
        """Ask it to leave the team cleanly (it says goodbye), then wait."""
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


if __name__ == "__main__":
    raise SystemExit(main())
