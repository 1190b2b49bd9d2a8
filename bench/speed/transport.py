"""Ask round-trip latency: local fast path, in-process transport, ZeroMQ inproc/ipc/tcp.

The ipc and tcp peers run in another OS process (``python -m btcap.bench.speed.transport
--peer``, see :mod:`bench.speed.transport_peers`). Peer figures measured in the same run:
blocking pyzmq on both sides (``raw_zmq_tcp_blocking``: the floor with no event loop at
all, and what every figure is given as a ratio to; ``raw_zmq_tcp_blocking_curve`` the
same over CURVE, what CURVE figures are also given against), pyzmq's own asyncio
DEALER/ROUTER echo (``raw_zmq_tcp``), and the cheapest ask an event loop allows, hand-
written without btcap (``floor_tcp*``, :mod:`bench.speed.transport_floor`): the table splits
btcap's gap to blocking pyzmq into the event loop's share and btcap's own. All scenarios
are set up at once and measured in interleaved rounds, so a machine whose load drifts
still gives every scenario the same conditions. Besides wall time, each scenario's CPU
time per ask is counted (``time.process_time`` here, the peer process's from ``/proc``:
every thread, so ZeroMQ's I/O threads count), which a shared machine's load moves far
less.

With uvloop installed (the optional ``fast`` extra) the tcp scenarios run a second
time with both sides on uvloop, against their own blocking floor in that pass.

Run ``python -m btcap.bench transport [--quick] [--loop asyncio|uvloop|both]``.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import shutil
import tempfile
import time
import uuid
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from typing import Any

import msgspec
import zmq
import zmq.asyncio

from btcap.actors import ActorSystem, Address, configure_logging
from btcap.bench.common import percentiles, write_result
from btcap.bench.cpumeter import cpu_of
from btcap.bench.speed.transport_floor import (
    floor_tcp,
    raw_zmq_tcp_blocking,
    serve_blocking,
    serve_floor,
)
from btcap.bench.speed.transport_peers import (
    LOOPS,
    Echo,
    Ping,
    Pong,
    child,
    peer_keys,
    registry,
    run_on,
    secure,
    serve_peer,
    serve_raw_peer,
    uvloop_installed,
)
from btcap.transports import InProcessNetwork, KeyPair, ZmqTransport
from btcap.transports.security import write_key_pair

__all__ = ["Ping", "Pong", "measure", "raw_zmq_tcp_blocking", "run", "zmq_tcp"]

FLOORS = (
    "floor_tcp",
    "floor_tcp_curve",
    "floor_tcp_pair",
    "floor_tcp_pair_curve",
    "raw_zmq_tcp_blocking",
    "raw_zmq_tcp_blocking_curve",
)
"""The hand-written floors of :mod:`bench.speed.transport_floor`, with blocking pyzmq last."""
SCENARIOS = (
    "local",
    "inproc_transport",
    "zmq_inproc",
    "zmq_ipc",
    "zmq_tcp",
    "zmq_tcp_curve",
    "raw_zmq_tcp",
    "raw_zmq_tcp_curve",
    *FLOORS,
)
TCP_SCENARIOS = ("zmq_tcp", "zmq_tcp_curve", *FLOORS)
"""What the uvloop pass measures: the runtime over tcp and its floors."""
FLOOR = "raw_zmq_tcp_blocking"
FLOOR_CURVE = "raw_zmq_tcp_blocking_curve"
SPLITS = (
    ("zmq_tcp", "floor_tcp_pair", FLOOR),
    ("zmq_tcp_curve", "floor_tcp_pair_curve", FLOOR_CURVE),
)
"""btcap's ask, the hand-written event-loop ask of the same shape, and blocking pyzmq:
how much of the gap is the event loop's and how much btcap's."""
_TCP = "tcp://127.0.0.1:*"
_PAYLOAD = "x" * 32

# -- scenarios: each yields an ``ask(i)`` that does one round trip, and its peer pids ------

Ask = Callable[[int], Awaitable[Any]]
Scenario = tuple[Ask, list[int]]


@contextlib.asynccontextmanager
async def _local() -> AsyncIterator[Scenario]:
    async with ActorSystem("local", registry=registry()) as system:
        ref = system.spawn(Echo(), "echo")

        async def ask(i: int) -> Any:
            return await ref.ask(Ping(i, _PAYLOAD))

        yield ask, []


@contextlib.asynccontextmanager
async def _inproc_transport() -> AsyncIterator[Scenario]:
    reg = registry()
    net = InProcessNetwork(reg)
    async with (
        ActorSystem(transport=net.transport("a"), registry=reg) as a,
        ActorSystem(transport=net.transport("b"), registry=reg) as b,
    ):
        b.spawn(Echo(), "echo")
        ref = a.ref(Address("b", "echo"))

        async def ask(i: int) -> Any:
            return await ref.ask(Ping(i, _PAYLOAD))

        yield ask, []


@contextlib.asynccontextmanager
async def _zmq_inproc() -> AsyncIterator[Scenario]:
    tag = uuid.uuid4().hex[:8]
    reg_a, reg_b = registry(), registry()
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

        yield ask, []


def _make_keys(folder: str) -> None:
    """Key pairs for the CURVE scenarios; ``folder/team`` is their allow-list."""
    os.mkdir(f"{folder}/team")
    for name in ("main-curve", "peer"):
        public, _ = write_key_pair(folder, name)
        shutil.copy(public, f"{folder}/team")


@contextlib.asynccontextmanager
async def _zmq_remote(
    system_id: str, bind: str, peer_bind: str, loop: str, keys: str | None = None
) -> AsyncIterator[Scenario]:
    """Our system here, the echo actor's system in another OS process (CURVE with keys)."""
    args = ("--peer", peer_bind, "--loop", loop, *(("--keys", keys) if keys else ()))
    with child(*args) as (endpoint, pid):
        reg = registry()
        transport = ZmqTransport(
            system_id, bind, reg, peers={"peer": endpoint}, **secure(system_id, keys)
        )
        async with ActorSystem(transport=transport, registry=reg) as system:
            ref = system.ref(Address("peer", "echo"))

            async def ask(i: int) -> Any:
                return await ref.ask(Ping(i, _PAYLOAD), timeout=10.0)

            yield ask, [pid]


def zmq_tcp(loop: str = "asyncio") -> contextlib.AbstractAsyncContextManager[Scenario]:
    """The runtime's ask over tcp to an echo actor in another process (no keys)."""
    return _zmq_remote("main-tcp", _TCP, _TCP, loop)


@contextlib.asynccontextmanager
async def _raw_zmq_tcp(loop: str, keys: str | None = None) -> AsyncIterator[Scenario]:
    """pyzmq's own asyncio sockets, DEALER here, ROUTER echo there (with ``keys``,
    CURVE-encrypted; no ZAP, which costs only at the handshake)."""
    args = ("--loop", loop, *(("--keys", keys) if keys else ()))
    with child("--raw-peer", _TCP, *args) as (endpoint, pid):
        sock = zmq.asyncio.Context.instance().socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        if keys is not None:
            mine, server = KeyPair.load(f"{keys}/main-curve.key_secret"), peer_keys(keys)
            sock.setsockopt(zmq.CURVE_SERVERKEY, server.public)
            sock.setsockopt(zmq.CURVE_PUBLICKEY, mine.public)
            sock.setsockopt(zmq.CURVE_SECRETKEY, mine.secret)
        sock.connect(endpoint)
        payload = msgspec.msgpack.encode(Ping(0, _PAYLOAD))
        try:

            async def ask(i: int) -> Any:
                await sock.send(payload)
                return await sock.recv()

            yield ask, [pid]
        finally:
            sock.close(0)


async def measure(ask: Ask, count: int, samples: list[float]) -> None:
    """Append ``count`` per-call latencies in microseconds to ``samples``."""
    clock = time.perf_counter_ns
    for i in range(count):
        t0 = clock()
        await ask(i)
        samples.append((clock() - t0) / 1000.0)


# -- the benchmark ----------------------------------------------------------------------


def _scenarios(
    tmp: str, loop: str
) -> dict[str, Callable[[], contextlib.AbstractAsyncContextManager[Scenario]]]:
    every: dict[str, Callable[[], contextlib.AbstractAsyncContextManager[Scenario]]] = {
        "local": _local,
        "inproc_transport": _inproc_transport,
        "zmq_inproc": _zmq_inproc,
        "zmq_ipc": lambda: _zmq_remote(
            "main-ipc", f"ipc://{tmp}/main.sock", f"ipc://{tmp}/peer.sock", loop
        ),
        "zmq_tcp": lambda: zmq_tcp(loop),
        "zmq_tcp_curve": lambda: _zmq_remote("main-curve", _TCP, _TCP, loop, tmp),
        "raw_zmq_tcp": lambda: _raw_zmq_tcp(loop),
        "raw_zmq_tcp_curve": lambda: _raw_zmq_tcp(loop, tmp),
        "floor_tcp": lambda: floor_tcp(loop),
        "floor_tcp_curve": lambda: floor_tcp(loop, tmp),
        "floor_tcp_pair": lambda: floor_tcp(loop, pair=True),
        "floor_tcp_pair_curve": lambda: floor_tcp(loop, tmp, pair=True),
        "raw_zmq_tcp_blocking": raw_zmq_tcp_blocking,
        "raw_zmq_tcp_blocking_curve": lambda: raw_zmq_tcp_blocking(tmp),
    }
    names = SCENARIOS if loop == "asyncio" else TCP_SCENARIOS
    return {name: every[name] for name in names}


async def _run_all(loop: str, warmup: int, count: int, rounds: int) -> dict[str, Any]:
    """Every scenario set up at once, then measured in interleaved rounds.

    On a shared machine the load drifts; interleaving gives each scenario the same
    conditions, so the ratios to the blocking floor hold even when absolutes move.
    """
    tmp = tempfile.mkdtemp(prefix="btcap-bench-")
    _make_keys(tmp)
    try:
        async with contextlib.AsyncExitStack() as stack:
            setups = {
                name: await stack.enter_async_context(make())
                for name, make in _scenarios(tmp, loop).items()
            }
            samples: dict[str, list[float]] = {name: [] for name in setups}
            cpu_here = dict.fromkeys(setups, 0.0)
            cpu_peer = dict.fromkeys(setups, 0.0)
            for ask, _pids in setups.values():
                for i in range(warmup):
                    await ask(i)
            per_round = max(1, count // rounds)
            for _ in range(rounds):
                gc.collect()
                for name, (ask, pids) in setups.items():
                    here, peer = time.process_time(), sum(cpu_of(p) for p in pids)
                    await measure(ask, per_round, samples[name])
                    cpu_here[name] += time.process_time() - here
                    cpu_peer[name] += sum(cpu_of(p) for p in pids) - peer
            asks = per_round * rounds
            return {
                name: {
                    **percentiles(values),
                    "cpu_here_us": cpu_here[name] / asks * 1e6,
                    "cpu_peer_us": cpu_peer[name] / asks * 1e6 if setups[name][1] else 0.0,
                }
                for name, values in samples.items()
            }
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _ratios(ask_us: dict[str, dict[str, float]]) -> dict[str, float]:
    floor = ask_us[FLOOR]["p50"]
    return {name: p["p50"] / floor for name, p in ask_us.items()}


def _blocking_of(name: str) -> str:
    """The blocking floor a scenario compares with: the CURVE one for a CURVE scenario."""
    return FLOOR_CURVE if name.endswith("_curve") else FLOOR


def _ratios_same_security(ask_us: dict[str, dict[str, float]]) -> dict[str, float]:
    return {name: p["p50"] / ask_us[_blocking_of(name)]["p50"] for name, p in ask_us.items()}


def _splits(ask_us: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """Per btcap tcp scenario: the event-loop floor's share of the gap and btcap's own."""
    out = {}
    for name, floor, blocking in SPLITS:
        ours, loop_floor, block = (ask_us[n]["p50"] for n in (name, floor, blocking))
        out[name] = {
            "to_blocking": ours / block,
            "loop_floor_to_blocking": loop_floor / block,
            "to_loop_floor": ours / loop_floor,
            "loop_share_of_gap": (loop_floor - block) / (ours - block) if ours > block else 1.0,
        }
    return out


def _table(loop: str, ask_us: dict[str, dict[str, float]]) -> str:
    ratio, same = _ratios(ask_us), _ratios_same_security(ask_us)
    lines = [
        f"ask round trip on {loop}: p50/p99 wall us; CPU us per ask here + in the peer process",
        f"{'scenario':<27} {'p50':>7} {'p99':>8} {'/floor':>7} {'/block':>7} "
        f"{'cpu here':>8} {'cpu peer':>8}",
        "-" * 79,
    ]
    for name, p in ask_us.items():
        lines.append(
            f"{name:<27} {p['p50']:>7.1f} {p['p99']:>8.1f} {ratio[name]:>7.2f} {same[name]:>7.2f} "
            f"{p['cpu_here_us']:>8.1f} {p['cpu_peer_us']:>8.1f}"
        )
    lines.append(
        f"/floor: to {FLOOR} (blocking pyzmq on both sides, same run); /block: to the "
        f"blocking floor of the same security ({FLOOR_CURVE} for *_curve)"
    )
    for name, split in _splits(ask_us).items():
        share = split["loop_share_of_gap"]
        said = f"{share:.0%}" if 0.0 <= share <= 1.0 else "lost in the noise"
        lines.append(
            f"{name}: {split['to_blocking']:.2f}x blocking = event-loop floor "
            f"{split['loop_floor_to_blocking']:.2f}x x btcap over that floor "
            f"{split['to_loop_floor']:.2f}x (the loop's share of the gap: {said})"
        )
    return "\n".join(lines)


def readme_row(ask_us: dict[str, dict[str, float]]) -> str:
    """The README performance table's ask row, from the stock loop's figures."""
    ours, block = ask_us["zmq_tcp"]["p50"], ask_us[FLOOR]["p50"]
    curve, block_curve = ask_us["zmq_tcp_curve"]["p50"], ask_us[FLOOR_CURVE]["p50"]
    floor, x = ask_us["floor_tcp_pair"]["p50"], "\u00d7"
    return (
        f"| ask round trip over ZeroMQ tcp (CURVE), another process | {ours:.0f} µs "
        f"({curve:.0f} µs) | blocking pyzmq {block:.0f} µs ({ours / block:.2f}{x}; CURVE "
        f"{block_curve:.0f} µs, {curve / block_curve:.2f}{x}); a hand-written asyncio ask "
        f"{floor:.0f} µs |"
    )


def run(quick: bool = False, loop: str = "both") -> dict[str, Any]:
    """Measure every scenario, print a table and write ``bench/results/transport.json``."""
    configure_logging("warning")  # hellos log at info; keep the table readable
    warmup, count = (500, 3_000) if quick else (3_000, 20_000)
    loops = [name for name in LOOPS if loop in (name, "both")]
    if loop == "both" and not uvloop_installed():
        loops = ["asyncio"]  # the fast extra is optional
    data: dict[str, Any] = {"samples": count, "warmup": warmup, "quick": quick, "floor": FLOOR}
    for name in loops:
        load = os.getloadavg()
        # Many short rounds: a burst of load elsewhere lands on every scenario alike.
        ask_us = run_on(name, _run_all(name, warmup, count, rounds=10 if quick else 40))
        key = "" if name == "asyncio" else f"_{name}"
        data[f"ask_us{key}"] = ask_us
        data[f"ratio_to_floor{key}"] = _ratios(ask_us)
        data[f"ratio_to_blocking_same_security{key}"] = _ratios_same_security(ask_us)
        data[f"gap_split{key}"] = _splits(ask_us)
        # Two processes share the machine's cores: a busy machine shows in the figures.
        data[f"loadavg{key}"] = {"before": load, "after": os.getloadavg()}
        print(_table(name, ask_us))
        print(f"load average before/after: {load[0]:.2f} / {os.getloadavg()[0]:.2f}\n")
    if "ask_us" in data:
        print(f"README row:\n{readme_row(data['ask_us'])}\n")
    path = write_result("transport", data)
    print(f"wrote {path}")
    return data


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m btcap.bench.speed.transport", description=__doc__
    )
    parser.add_argument("--quick", action="store_true", help="fewer samples, for CI smoke runs")
    parser.add_argument(
        "--loop",
        choices=(*LOOPS, "both"),
        default="both",
        help="event loop(s) to measure on (uvloop: the optional 'fast' extra); default both",
    )
    role = parser.add_mutually_exclusive_group()
    role.add_argument("--peer", metavar="BIND", help="(internal) serve an echo actor system")
    role.add_argument("--raw-peer", metavar="BIND", help="(internal) serve a raw zmq echo")
    parser.add_argument("--keys", metavar="DIR", help="(internal) CURVE keys of a peer")
    role.add_argument(
        "--raw-peer-blocking", metavar="BIND", help="(internal) serve a blocking zmq echo"
    )
    role.add_argument(
        "--floor-peer", metavar="BIND", help="(internal) serve a hand-written event-loop echo"
    )
    parser.add_argument("--reply-to", metavar="ENDPOINT", help="(internal) the floor's shape")
    args = parser.parse_args(argv)
    peer_loop = "asyncio" if args.loop == "both" else args.loop
    if args.peer:
        configure_logging("warning")  # to stderr: stdout carries the READY line
        run_on(peer_loop, serve_peer(args.peer, args.keys))
    elif args.raw_peer:
        run_on(peer_loop, serve_raw_peer(args.raw_peer, args.keys))
    elif args.raw_peer_blocking:
        serve_blocking(args.raw_peer_blocking, args.keys)
    elif args.floor_peer:
        run_on(peer_loop, serve_floor(args.floor_peer, args.keys, args.reply_to))
    else:
        run(quick=args.quick, loop=args.loop)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
