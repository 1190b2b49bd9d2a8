"""Ask round-trip latency: local fast path, in-process transport, ZeroMQ inproc/ipc/tcp.

The ipc and tcp peers run in another OS process (``python -m btcap.bench.transport --peer``).
Two peer figures are measured in the same run: pyzmq's own asyncio DEALER/ROUTER echo
over tcp (``raw_zmq_tcp``, what the runtime is compared to as a ratio) and blocking
pyzmq on both sides (``raw_zmq_tcp_blocking``, the floor with no event loop at all).
All scenarios are set up at once and measured in interleaved rounds, so a machine whose
load drifts during the run still gives every scenario the same conditions.

Run ``python -m btcap.bench transport [--quick]`` or ``python -m btcap.bench.transport [--quick]``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator, Sequence
from typing import Any

import msgspec
import zmq
import zmq.asyncio

from btcap.actors import Actor, ActorSystem, Address, Message, configure_logging, handler
from btcap.bench.common import percentiles, write_result
from btcap.transports import InProcessNetwork, KeyPair, MessageRegistry, ZmqTransport
from btcap.transports.security import write_key_pair

__all__ = ["Ping", "Pong", "run"]

SCENARIOS = (
    "local",
    "inproc_transport",
    "zmq_inproc",
    "zmq_ipc",
    "zmq_tcp",
    "zmq_tcp_curve",
    "raw_zmq_tcp",
    "raw_zmq_tcp_curve",
    "raw_zmq_tcp_blocking",
)
_READY = "READY "
_TCP = "tcp://127.0.0.1:*"
_PAYLOAD = "x" * 32


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


def _registry() -> MessageRegistry:
    return MessageRegistry([Ping, Pong])


# -- scenarios: each yields an ``ask(i)`` that does one round trip ------------------------

Ask = Callable[[int], Awaitable[Any]]


@contextlib.asynccontextmanager
async def _local() -> AsyncIterator[Ask]:
    async with ActorSystem("local", registry=_registry()) as system:
        ref = system.spawn(Echo(), "echo")

        async def ask(i: int) -> Any:
            return await ref.ask(Ping(i, _PAYLOAD))

        yield ask


@contextlib.asynccontextmanager
async def _inproc_transport() -> AsyncIterator[Ask]:
    reg = _registry()
    net = InProcessNetwork(reg)
    async with (
        ActorSystem(transport=net.transport("a"), registry=reg) as a,
        ActorSystem(transport=net.transport("b"), registry=reg) as b,
    ):
        b.spawn(Echo(), "echo")
        ref = a.ref(Address("b", "echo"))

        async def ask(i: int) -> Any:
            return await ref.ask(Ping(i, _PAYLOAD))

        yield ask


@contextlib.asynccontextmanager
async def _zmq_inproc() -> AsyncIterator[Ask]:
    tag = uuid.uuid4().hex[:8]
    reg_a, reg_b = _registry(), _registry()
    tb = ZmqTransport("b", f"inproc://bench-b-{tag}", reg_b)
    ta = ZmqTransport("a", f"inproc://bench-a-{tag}", reg_a, peers={"b": tb.endpoint})
    async with (
        ActorSystem(transport=tb, registry=reg_b) as b,
        ActorSystem(transport=ta, registry=reg_a) as a,
    ):
        b.spawn(Echo(), "echo")
        ref = a.ref(Address("b", "echo"))

        async def ask(i: int) -> Any:
            return await ref.ask(Ping(i, _PAYLOAD))

        yield ask


def _make_keys(folder: str) -> None:
    """Key pairs for the CURVE scenarios; ``folder/team`` is their allow-list."""
    os.mkdir(f"{folder}/team")
    for name in ("main-curve", "peer"):
        public, _ = write_key_pair(folder, name)
        shutil.copy(public, f"{folder}/team")


def _secure(name: str, keys: str | None) -> dict[str, Any]:
    if keys is None:
        return {}
    return {"keys": f"{keys}/{name}.key_secret", "trusted": f"{keys}/team"}


@contextlib.asynccontextmanager
async def _zmq_remote(
    system_id: str, bind: str, peer_bind: str, keys: str | None = None
) -> AsyncIterator[Ask]:
    """Our system here, the echo actor's system in another OS process (CURVE with keys)."""
    with _child("--peer", peer_bind, *(("--keys", keys) if keys else ())) as endpoint:
        reg = _registry()
        transport = ZmqTransport(
            system_id, bind, reg, peers={"peer": endpoint}, **_secure(system_id, keys)
        )
        async with ActorSystem(transport=transport, registry=reg) as system:
            ref = system.ref(Address("peer", "echo"))

            async def ask(i: int) -> Any:
                return await ref.ask(Ping(i, _PAYLOAD), timeout=10.0)

            yield ask


@contextlib.asynccontextmanager
async def _raw_zmq_tcp(keys: str | None = None) -> AsyncIterator[Ask]:
    """The peer figure: pyzmq's own asyncio sockets, DEALER here, ROUTER echo there
    (with ``keys``, CURVE-encrypted; no ZAP, which costs only at the handshake)."""
    args = ("--keys", keys) if keys else ()
    with _child("--raw-peer", "tcp://127.0.0.1:*", *args) as endpoint:
        sock = zmq.asyncio.Context.instance().socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        if keys is not None:
            mine, server = KeyPair.load(f"{keys}/main-curve.key_secret"), _peer_keys(keys)
            sock.setsockopt(zmq.CURVE_SERVERKEY, server.public)
            sock.setsockopt(zmq.CURVE_PUBLICKEY, mine.public)
            sock.setsockopt(zmq.CURVE_SECRETKEY, mine.secret)
        sock.connect(endpoint)
        payload = msgspec.msgpack.encode(Ping(0, _PAYLOAD))
        try:

            async def ask(i: int) -> Any:
                await sock.send(payload)
                return await sock.recv()

            yield ask
        finally:
            sock.close(0)


@contextlib.asynccontextmanager
async def _raw_zmq_tcp_blocking() -> AsyncIterator[Ask]:
    """The floor: blocking pyzmq on both sides, no event loop in the way."""
    with _child("--raw-peer-blocking", "tcp://127.0.0.1:*") as endpoint:
        ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
        sock = ctx.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        sock.connect(endpoint)
        payload = msgspec.msgpack.encode(Ping(0, _PAYLOAD))
        try:

            async def ask(i: int) -> Any:
                sock.send(payload)
                return sock.recv()

            yield ask
        finally:
            sock.close(0)
            ctx.term()


async def _measure(ask: Ask, count: int, samples: list[float]) -> None:
    """Append ``count`` per-call latencies in microseconds to ``samples``."""
    clock = time.perf_counter_ns
    for i in range(count):
        t0 = clock()
        await ask(i)
        samples.append((clock() - t0) / 1000.0)


# -- peer processes ---------------------------------------------------------------------


@contextlib.contextmanager
def _child(*args: str) -> Iterator[str]:
    """Run a peer process; yield the endpoint it bound; stop it (stdin EOF) on exit."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "btcap.bench.transport", *args],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        if not line.startswith(_READY):
            raise RuntimeError(f"peer {args} did not start: {line!r}")
        yield line[len(_READY) :].strip()
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


async def _until_stdin_closes() -> None:
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


def _peer_keys(keys: str) -> KeyPair:
    return KeyPair.load(f"{keys}/peer.key_secret")


async def _serve_peer(bind: str, keys: str | None) -> None:
    reg = _registry()
    transport = ZmqTransport("peer", bind, reg, **_secure("peer", keys))
    async with ActorSystem(transport=transport, registry=reg) as system:
        system.spawn(Echo(), "echo")
        print(_READY + transport.endpoint, flush=True)
        await _until_stdin_closes()


def _serve_raw_peer_blocking(bind: str) -> None:
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    sock = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.bind(bind)
    print(_READY + sock.getsockopt_string(zmq.LAST_ENDPOINT), flush=True)
    poller = zmq.Poller()
    poller.register(sock, zmq.POLLIN)
    poller.register(sys.stdin.fileno(), zmq.POLLIN)
    try:
        while True:
            ready = dict(poller.poll())
            if sock in ready:
                sock.send_multipart(sock.recv_multipart())
            if sys.stdin.fileno() in ready and not os.read(sys.stdin.fileno(), 4096):
                return
    finally:
        sock.close(0)
        ctx.term()


async def _serve_raw_peer(bind: str, keys: str | None) -> None:
    ctx = zmq.asyncio.Context.instance()
    sock = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    if keys is not None:
        pair = _peer_keys(keys)
        sock.setsockopt(zmq.CURVE_SERVER, 1)
        sock.setsockopt(zmq.CURVE_SECRETKEY, pair.secret)
    sock.bind(bind)
    print(_READY + sock.getsockopt_string(zmq.LAST_ENDPOINT), flush=True)

    async def echo() -> None:
        while True:
            frames = await sock.recv_multipart()
            await sock.send_multipart(frames)

    task = asyncio.ensure_future(echo())
    try:
        await _until_stdin_closes()
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
        sock.close(0)


# -- the benchmark ----------------------------------------------------------------------


async def _run_all(warmup: int, count: int, rounds: int) -> dict[str, dict[str, float]]:
    """Every scenario set up at once, then measured in interleaved rounds.

    On a shared machine the load drifts; interleaving gives each scenario the same
    conditions, so the ratios to the raw pyzmq figure hold even when absolutes move.
    """
    tmp = tempfile.mkdtemp(prefix="btcap-bench-")
    _make_keys(tmp)
    try:
        async with contextlib.AsyncExitStack() as stack:
            scenarios: dict[str, Callable[[], contextlib.AbstractAsyncContextManager[Ask]]] = {
                "local": _local,
                "inproc_transport": _inproc_transport,
                "zmq_inproc": _zmq_inproc,
                "zmq_ipc": lambda: _zmq_remote(
                    "main-ipc", f"ipc://{tmp}/main.sock", f"ipc://{tmp}/peer.sock"
                ),
                "zmq_tcp": lambda: _zmq_remote("main-tcp", _TCP, _TCP),
                "zmq_tcp_curve": lambda: _zmq_remote("main-curve", _TCP, _TCP, tmp),
                "raw_zmq_tcp": _raw_zmq_tcp,
                "raw_zmq_tcp_curve": lambda: _raw_zmq_tcp(tmp),
                "raw_zmq_tcp_blocking": _raw_zmq_tcp_blocking,
            }
            asks = {
                name: await stack.enter_async_context(make()) for name, make in scenarios.items()
            }
            samples: dict[str, list[float]] = {name: [] for name in asks}
            for ask in asks.values():
                for i in range(warmup):
                    await ask(i)
            per_round = max(1, count // rounds)
            for _ in range(rounds):
                gc.collect()
                for name, ask in asks.items():
                    await _measure(ask, per_round, samples[name])
            return {name: percentiles(values) for name, values in samples.items()}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _table(ask_us: dict[str, dict[str, float]]) -> str:
    raw = ask_us["raw_zmq_tcp"]["p50"]
    lines = [
        f"{'ask round trip':<22} {'p50 us':>9} {'p99 us':>9} {'p50 / raw tcp':>14}",
        "-" * 57,
    ]
    for name in SCENARIOS:
        p = ask_us[name]
        lines.append(f"{name:<22} {p['p50']:>9.1f} {p['p99']:>9.1f} {p['p50'] / raw:>14.2f}")
    curve = ask_us["zmq_tcp_curve"]["p50"] / ask_us["raw_zmq_tcp_curve"]["p50"]
    lines.append(f"zmq_tcp_curve / raw_zmq_tcp_curve (p50): {curve:.2f}")
    return "\n".join(lines)


def run(quick: bool = False) -> dict[str, Any]:
    """Measure every scenario, print a table and write ``bench/results/transport.json``."""
    configure_logging("warning")  # hellos log at info; keep the table readable
    warmup, count = (500, 3_000) if quick else (3_000, 20_000)
    load = os.getloadavg()
    ask_us = asyncio.run(_run_all(warmup, count, rounds=10))
    data: dict[str, Any] = {
        "ask_us": ask_us,
        "ratio_to_raw_zmq_tcp": {
            name: ask_us[name]["p50"] / ask_us["raw_zmq_tcp"]["p50"] for name in SCENARIOS
        },
        "curve_ratio_to_raw_zmq_tcp_curve": ask_us["zmq_tcp_curve"]["p50"]
        / ask_us["raw_zmq_tcp_curve"]["p50"],
        "samples": count,
        "warmup": warmup,
        "quick": quick,
        # Two processes share the machine's cores: a busy machine shows in the figures.
        "loadavg_before": load,
        "loadavg_after": os.getloadavg(),
    }
    print(_table(ask_us))
    print(f"load average before/after: {load[0]:.2f} / {data['loadavg_after'][0]:.2f}")
    path = write_result("transport", data)
    print(f"wrote {path}")
    return data


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m btcap.bench.transport", description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer samples, for CI smoke runs")
    role = parser.add_mutually_exclusive_group()
    role.add_argument("--peer", metavar="BIND", help="(internal) serve an echo actor system")
    role.add_argument("--raw-peer", metavar="BIND", help="(internal) serve a raw zmq echo")
    parser.add_argument("--keys", metavar="DIR", help="(internal) CURVE keys of a peer")
    role.add_argument(
        "--raw-peer-blocking", metavar="BIND", help="(internal) serve a blocking zmq echo"
    )
    args = parser.parse_args(argv)
    if args.peer:
        configure_logging("warning")  # to stderr: stdout carries the READY line
        asyncio.run(_serve_peer(args.peer, args.keys))
    elif args.raw_peer:
        asyncio.run(_serve_raw_peer(args.raw_peer, args.keys))
    elif args.raw_peer_blocking:
        _serve_raw_peer_blocking(args.raw_peer_blocking)
    else:
        run(quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
