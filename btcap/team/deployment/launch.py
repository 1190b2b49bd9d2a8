"""Run robots as separate OS processes talking ZeroMQ: one or more :class:`Agent` per
process.

``python -m btcap.team.deployment.launch SPEC_JSON`` runs the agent described by an
:class:`AgentSpec` (a JSON object), or several agents in one process (a JSON array of
specs, each with its own actor system, transport and port), until stdin closes or it is
terminated. For every agent, once it listens, the process prints one stdout line: a JSON
object with the robot and its bound endpoint, so a parent knows where to connect.
:func:`spawn_agent` and :func:`spawn_agents` (or, in async code,
:func:`~btcap.team.deployment.spawn.open_agents`) do this from Python and return a
handle that can stop or kill the process (for failure experiments). A bad spec exits
with status 2 and a message naming the field; an agent that fails is logged with its
robot, printed on stderr and exits with status 1.

Many agents per process keep large teams affordable on small machines (50 bidders need
not be 50 interpreters); they still talk to each other and to everyone else over their
own sockets, exactly as robots in separate processes do.
"""

from __future__ import annotations

import asyncio
import functools
import inspect
import json
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

import anyio
import msgspec

from btcap.actors import Clock, configure_logging
from btcap.actors.loops import loop_factory
from btcap.errors import BtcapError
from btcap.team.capabilities.implementation import Implementation
from btcap.team.capabilities.loader import load_callable
from btcap.team.deployment.agentspec import AgentSpec, agent_config, agent_keys, check_specs
from btcap.team.deployment.spawn import AgentProcess, AsyncAgentProcess, spawn_agent, spawn_agents
from btcap.team.deployment.supervised import stdin_closed, watchable
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport
from btcap.transports.log import get_logger

__all__ = [
    "AgentFailed",
    "AgentProcess",
    "AgentSpec",
    "AsyncAgentProcess",
    "main",
    "run_agent",
    "run_agents",
    "spawn_agent",
    "spawn_agents",
]

log = get_logger(__name__)


class AgentFailed(BtcapError):
    """An agent run by :func:`run_agents` stopped with an error (chained as the cause)."""

    def __init__(self, robot: str, error: BaseException) -> None:
        super().__init__(f"agent {robot}: {type(error).__name__}: {error}")
        self.robot = robot


def _load(spec: AgentSpec, field: str, ref: str) -> Callable[..., Any]:
    try:
        return load_callable(ref)
    except ValueError as exc:
        raise ValueError(f"agent spec {spec.robot!r}: {field}: {exc}") from None


def _factories(spec: AgentSpec) -> tuple[Callable[[], Any] | None, Callable[[], Any] | None]:
    """The spec's implementation and registry factories, bound to their arguments.

    ValueError names the field: a bad reference, or ``factory_args`` the factory does
    not take (checked against its signature, so nothing runs yet).
    """
    bound = None
    if spec.factory:
        factory = _load(spec, "factory", spec.factory)
        try:
            inspect.signature(factory).bind(spec.robot, **spec.factory_args)
        except TypeError as exc:
            raise ValueError(f"agent spec {spec.robot!r}: factory_args: {exc}") from None
        bound = functools.partial(factory, spec.robot, **spec.factory_args)
    registry = _load(spec, "registry", spec.registry) if spec.registry else None
    return bound, registry


async def run_agent(spec: AgentSpec, *, ready: Callable[[str], None] | None = None) -> None:
    """Run one agent until cancelled; ``ready(endpoint)`` is called once it listens.

    ``spec.factory`` returns an iterable of implementations, or an object with
    ``implementations`` and ``actors`` (a mapping of path to actor to spawn beside the
    runtime, e.g. a simulated robot's body); ``spec.registry`` returns the
    :class:`~transports.MessageRegistry` the robot speaks (default: btcap's protocol).
    """
    cfg = agent_config(spec)
    make, make_registry = _factories(spec)
    made = make() if make is not None else []
    impls: list[Implementation]
    extra: dict[str, Any] = {}
    if hasattr(made, "implementations"):
        impls = list(made.implementations)
        extra = dict(getattr(made, "actors", {}))
    else:
        impls = list(made)
    registry = make_registry() if make_registry is not None else protocol_registry()
    keys, trusted = agent_keys(spec)
    transport = ZmqTransport(
        spec.robot, spec.bind, registry, peers=dict(spec.peers), keys=keys, trusted=trusted
    )
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
        await anyio.sleep_forever()


async def run_agents(
    specs: Sequence[AgentSpec], *, ready: Callable[[str, str], None] | None = None
) -> None:
    """Run several agents in this event loop until cancelled, or until one of them fails.

    ``ready(robot, endpoint)`` is called for each agent once it listens. A failing agent
    is logged with its robot and stops the others; the failures are raised as an
    ExceptionGroup of :class:`AgentFailed`.
    """
    check_specs(specs)
    async with anyio.create_task_group() as tg:
        for s in specs:
            tg.start_soon(_run_logged, s, ready, name=f"agent {s.robot}")


async def _run_logged(spec: AgentSpec, ready: Callable[[str, str], None] | None) -> None:
    try:
        await run_agent(spec, ready=None if ready is None else functools.partial(ready, spec.robot))
    except Exception as exc:
        log.error("launch.agent_failed", robot=spec.robot, exc_info=exc)
        raise AgentFailed(spec.robot, exc) from exc


async def _main_async(specs: Sequence[AgentSpec]) -> None:
    def announce(robot: str, endpoint: str) -> None:
        line = json.dumps({"robot": robot, "endpoint": endpoint, "pid": os.getpid()})
        print(line, flush=True)

    async with anyio.create_task_group() as tg:
        tg.start_soon(_cancel_on_signal, tg.cancel_scope)
        # Stop when the parent closes our stdin (it went away or wants us gone). A stdin
        # that cannot be watched (/dev/null, a file) means: run until terminated.
        if watchable(sys.stdin):
            tg.start_soon(_cancel_on_eof, tg.cancel_scope)
        await run_agents(specs, ready=announce)


async def _cancel_on_signal(scope: anyio.CancelScope) -> None:
    with anyio.open_signal_receiver(signal.SIGTERM, signal.SIGINT) as signals:
        async for _ in signals:
            scope.cancel()
            return


async def _cancel_on_eof(scope: anyio.CancelScope) -> None:
    await stdin_closed()
    scope.cancel()


def _decode_specs(text: str) -> list[AgentSpec]:
    decoded = msgspec.json.decode(text, type=AgentSpec | list[AgentSpec])
    specs = [decoded] if isinstance(decoded, AgentSpec) else decoded
    check_specs(specs)
    return specs


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m btcap.team.deployment.launch SPEC_JSON``: 0 when stopped, 2 for a bad
    spec, 1 when an agent failed (each failure is printed on stderr, naming its robot)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print(
            "usage: python -m btcap.team.deployment.launch SPEC_JSON"
            "  (one spec object or an array)",
            file=sys.stderr,
        )
        return 2
    try:
        specs = _decode_specs(args[0])
        for s in specs:
            _factories(s)
    except msgspec.ValidationError as exc:  # names the field, e.g. an unknown key
        print(f"agent spec: {exc}", file=sys.stderr)
        return 2
    except msgspec.DecodeError as exc:
        print(f"agent spec: not valid JSON ({exc})", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"agent spec: {exc}", file=sys.stderr)
        return 2
    try:
        factory = loop_factory()  # uvloop when installed: see actors/loops.py
    except ValueError as exc:
        print(f"agent: {exc}", file=sys.stderr)
        return 2
    configure_logging(specs[0].log_level)
    try:
        with asyncio.Runner(loop_factory=factory) as runner:
            runner.run(_main_async(specs))
    except KeyboardInterrupt:
        pass
    except BaseExceptionGroup as group:
        failed, other = group.split(AgentFailed)
        for failure in _leaves(failed):
            print(failure, file=sys.stderr)
        if other is not None:
            raise other from None
        return 1
    return 0


def _leaves(exc: BaseException | None) -> list[BaseException]:
    if isinstance(exc, BaseExceptionGroup):
        return [leaf for sub in exc.exceptions for leaf in _leaves(sub)]
    return [] if exc is None else [exc]


if __name__ == "__main__":
    raise SystemExit(main())
