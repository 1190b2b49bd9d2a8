"""The other side of the ask benchmark: echo peers in their own OS processes.

``python -m btcap.bench.speed.transport --peer BIND`` serves an echo actor system; ``--raw-peer``
a pyzmq asyncio ROUTER echo; ``--raw-peer-blocking`` a blocking one. Each prints
``READY ENDPOINT`` and lives until its stdin closes. ``--loop uvloop`` runs the peer on
uvloop (the optional ``fast`` extra).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
from collections.abc import Coroutine, Iterator
from typing import Any, TypeVar

import zmq
import zmq.asyncio

from btcap.actors import Actor, ActorSystem, Message, handler
from btcap.transports import KeyPair, MessageRegistry, ZmqTransport

__all__ = [
    "LOOPS",
    "READY",
    "Echo",
    "Ping",
    "Pong",
    "child",
    "peer_keys",
    "registry",
    "run_on",
    "secure",
    "serve_peer",
    "serve_raw_peer",
    "until_stdin_closes",
    "uvloop_installed",
]

T = TypeVar("T")
READY = "READY "
LOOPS = ("asyncio", "uvloop")


class Ping(Message):
    seq: int
    text: str


class Pong(Message):
    seq: int


class Echo(Actor):
    """Replies from a sync handler, so local asks take the direct-call fast path."""

    @handler
    def ping(self, msg: Ping) -> Pong:
        return Pong(msg.seq)


def registry() -> MessageRegistry:
    return MessageRegistry([Ping, Pong])


def run_on(loop: str, coro: Coroutine[Any, Any, T]) -> T:
    """Run ``coro`` on the stock asyncio loop or on uvloop (ImportError if not installed)."""
    if loop == "uvloop":
        try:
            import uvloop
        except ImportError:
            coro.close()
            raise
        return uvloop.run(coro)
    return asyncio.run(coro)


def uvloop_installed() -> bool:
    try:
        import uvloop  # noqa: F401
    except ImportError:
        return False
    return True


@contextlib.contextmanager
def child(*args: str) -> Iterator[tuple[str, int]]:
    """Run a peer process; yield the endpoint it bound and its pid; stop it on exit."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "btcap.bench.speed.transport", *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        if not line.startswith(READY):
            raise RuntimeError(f"peer {args} did not start: {line!r}")
        yield line[len(READY) :].strip(), proc.pid
    finally:
        if proc.stdin is not None:
            proc.stdin.close()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


async def until_stdin_closes() -> None:
    """Peers live until their parent closes our stdin (or dies, which closes it too)."""
    loop = asyncio.get_running_loop()
    done = loop.create_future()
    fd = sys.stdin.fileno()

    def readable() -> None:
        if not os.read(fd, 4096) and not done.done():
            done.set_result(None)

    loop.add_reader(fd, readable)
    try:
        await done
    finally:
        loop.remove_reader(fd)


def peer_keys(keys: str) -> KeyPair:
    return KeyPair.load(f"{keys}/peer.key_secret")


def secure(name: str, keys: str | None) -> dict[str, Any]:
    if keys is None:
        return {}
    return {"keys": f"{keys}/{name}.key_secret", "trusted": f"{keys}/team"}


async def serve_peer(bind: str, keys: str | None) -> None:
    reg = registry()
    transport = ZmqTransport("peer", bind, reg, **secure("peer", keys))
    async with ActorSystem(transport=transport, registry=reg) as system:
        system.spawn(Echo(), "echo")
        print(READY + transport.endpoint, flush=True)
        await until_stdin_closes()


async def serve_raw_peer(bind: str, keys: str | None) -> None:
    ctx = zmq.asyncio.Context.instance()
    sock = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    if keys is not None:
        pair = peer_keys(keys)
        sock.setsockopt(zmq.CURVE_SERVER, 1)
        sock.setsockopt(zmq.CURVE_SECRETKEY, pair.secret)
    sock.bind(bind)
    print(READY + sock.getsockopt_string(zmq.LAST_ENDPOINT), flush=True)

    async def echo() -> None:
        while True:
            frames = await sock.recv_multipart()
            await sock.send_multipart(frames)

    task = asyncio.ensure_future(echo())
    try:
        await until_stdin_closes()
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        sock.close(0)
