"""The floor for an auction round over tcp: a hand-written round with no btcap at all.

What btcap's auction round (:mod:`bench.speed.auction`) cannot beat on this machine, measured
in the same run and in the same process layout: N bidders dealt round robin over the
same number of bidder processes, each bidder with its own sockets and port as btcap's
agents have (a ROUTER bound to receive, a DEALER to the auctioneer's ROUTER to answer);
the auctioneer binds a ROUTER and holds a DEALER to each bidder. One round is what
btcap's is, message for message: a call for bids to N bidders, N bids back, an award to
the cheapest, its accept back (the round's time ends there), then a cancel to the
winner (its send is timed: a few µs). Messages are msgpack arrays padded to the size of
btcap's frames (:data:`SIZES`), each decoded by its receiver, which checks the round
number, and nothing else: no envelope, routing, timers, checks of who sent it, heartbeats.

Two variants, each in its own bidder processes:

- ``blocking``: bidders wait in a ``zmq.Poller`` over their ROUTERs, the auctioneer in a
  blocking ``recv``: no event loop at all;
- ``asyncio``: both sides read ZeroMQ as btcap does, ``loop.add_reader`` on each ROUTER's
  descriptor, draining while ``zmq.EVENTS`` says POLLIN, ``NOBLOCK`` recv and send; the
  auctioneer awaits one Future for the bids and one for the accept.

With ``curve`` every ROUTER is a CURVE server and every DEALER a client (one key pair
per side: the per-message cost of CURVE does not depend on whose keys).

Run ``python -m btcap.bench.speed.auction_floor [--quick]`` for the floor alone.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import os
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from typing import Any

import zmq

from btcap.bench.common import percentiles
from btcap.bench.cpumeter import cpu_of
from btcap.bench.speed.auction_floor_peers import (
    ACCEPT,
    AWARD,
    BID,
    CALL,
    CANCEL,
    EVENTS,
    KEYS_ENV,
    NOBLOCK,
    POLLIN,
    READY,
    SIZES,
    VARIANTS,
    Keys,
    dealer,
    decode,
    make_keys,
    message,
    router,
)

__all__ = [
    "SIZES",
    "VARIANTS",
    "FloorReference",
    "FloorRound",
    "floor_reference",
    "floor_round",
    "measure_floor",
    "spread",
]

# -- the auctioneer (this process) ----------------------------------------------------


class FloorRound:
    """An auctioneer and its bidder processes, up until closed; :meth:`round` runs one."""

    def __init__(self, variant: str, bidders: int, processes: int, keys: Keys | None) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"auction floor: variant {variant!r}, expected one of {VARIANTS}")
        self.variant = variant
        self.pids: list[int] = []
        self._fd: int | None = None
        self._ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
        self._router = router(self._ctx, keys)
        self._procs: list[subprocess.Popen[str]] = []
        self._dealers: list[zmq.Socket[bytes]] = []
        self._rnd = 0
        endpoint = self._router.getsockopt_string(zmq.LAST_ENDPOINT)
        groups = [list(range(p, bidders, processes)) for p in range(min(processes, bidders))]
        env = dict(os.environ)
        if keys is not None:
            env[KEYS_ENV] = b" ".join(keys).decode()  # z85 has no space
        for group in groups:
            args = ("--ids", ",".join(map(str, group)), "--auctioneer", endpoint)
            self._procs.append(
                subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "btcap.bench.speed.auction_floor_peers",
                        "--serve",
                        variant,
                        *args,
                    ],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    text=True,
                    env=env,
                )
            )
        ends: dict[int, str] = {}
        for proc, group in zip(self._procs, groups, strict=True):
            assert proc.stdout is not None
            line = proc.stdout.readline()
            if not line.startswith(READY):
                self.close()
                raise RuntimeError(f"auction floor: bidders {group} did not start: {line!r}")
            ends.update(zip(group, line[len(READY) :].split(), strict=True))
            self.pids.append(proc.pid)
        self._dealers = [dealer(self._ctx, keys, ends[i]) for i in range(bidders)]
        #: ``round(n)``: one round with the first ``n`` bidders; returns the winner.
        self.round: Callable[[int], Awaitable[int]] = (
            self._blocking if variant == "blocking" else self._async
        )
        self._fut: asyncio.Future[int] | None = None
        self._want = (BID, 0, 0)  # kind, round, how many
        self._got = 0
        self._best = (float("inf"), -1)

    async def _blocking(self, n: int) -> int:
        self._rnd = rnd = self._rnd + 1
        call, recv = message(CALL, rnd), self._router.recv_multipart
        for sock in self._dealers[:n]:
            sock.send(call)
        best, got = (float("inf"), -1), 0
        while got < n:
            kind, r, bidder, cost, _ = decode(recv()[1])
            if kind == BID and r == rnd:
                got += 1
                best = min(best, (cost, bidder))
        winner = self._dealers[best[1]]
        winner.send(message(AWARD, rnd))
        while True:
            kind, r, bidder, _, _ = decode(recv()[1])
            if kind == ACCEPT and r == rnd:
                break
        winner.send(message(CANCEL, rnd))
        return bidder

    def _readable(self) -> None:
        get, recv = self._router.get, self._router.recv
        while get(EVENTS) & POLLIN:  # type: ignore[operator]
            recv(NOBLOCK)  # the bidder's routing id
            kind, r, bidder, cost, _ = decode(recv(NOBLOCK))
            want, rnd, n = self._want
            if kind != want or r != rnd:
                continue
            if kind == BID:
                self._got += 1
                self._best = min(self._best, (cost, bidder))
                if self._got < n:
                    continue
            fut = self._fut
            if fut is not None and not fut.done():
                fut.set_result(bidder if kind == ACCEPT else self._best[1])

    async def _async(self, n: int) -> int:
        loop = asyncio.get_running_loop()
        if self._fd is None:
            fd = self._router.getsockopt(zmq.FD)
            assert isinstance(fd, int)
            self._fd = fd
            loop.add_reader(fd, self._readable)
        self._rnd = rnd = self._rnd + 1
        self._want, self._got, self._best = (BID, rnd, n), 0, (float("inf"), -1)
        self._fut = loop.create_future()
        call = message(CALL, rnd)
        for sock in self._dealers[:n]:
            sock.send(call, NOBLOCK)
        best = await self._fut
        self._want = (ACCEPT, rnd, 1)
        self._fut = loop.create_future()
        winner = self._dealers[best]
        winner.send(message(AWARD, rnd), NOBLOCK)
        bidder = await self._fut
        winner.send(message(CANCEL, rnd), NOBLOCK)
        return bidder

    def close(self) -> None:
        if self._fd is not None:
            with contextlib.suppress(RuntimeError):  # no loop running any more
                asyncio.get_running_loop().remove_reader(self._fd)
            self._fd = None
        for proc in self._procs:
            proc.stdin.close()  # type: ignore[union-attr]
        for proc in self._procs:
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            proc.stdout.close()  # type: ignore[union-attr]
        for sock in (self._router, *self._dealers):
            sock.close(0)
        self._ctx.term()


@contextlib.asynccontextmanager
async def floor_round(
    variant: str, bidders: int, processes: int, curve: bool = False
) -> AsyncIterator[FloorRound]:
    """An auctioneer with ``bidders`` bidders over ``processes`` processes; every bidder
    has answered a round before this yields."""
    floor = FloorRound(variant, bidders, processes, make_keys() if curve else None)
    try:
        for _ in range(3):  # connections made, CURVE handshakes done
            await floor.round(bidders)
        yield floor
    finally:
        floor.close()


async def measure_floor(
    floor: FloorRound, n: int, count: int, samples: list[float], cpu: list[float] | None = None
) -> None:
    """Append ``count`` rounds' wall times (ms) with ``n`` bidders to ``samples``; add CPU
    seconds (here, bidder processes) to ``cpu``."""
    clock, round_, pids = time.perf_counter_ns, floor.round, floor.pids
    gc.collect()
    here, there = time.process_time(), sum(cpu_of(p) for p in pids)
    for _ in range(count):
        t0 = clock()
        await round_(n)
        samples.append((clock() - t0) / 1e6)
    if cpu is not None:
        cpu[0] += time.process_time() - here
        cpu[1] += sum(cpu_of(p) for p in pids) - there


def spread(samples: Sequence[float]) -> dict[str, float]:
    """p50, p90 and p99 of ``samples``."""
    ordered = sorted(samples)
    return {**percentiles(ordered), "p90": ordered[round(0.9 * (len(ordered) - 1))]}


class FloorReference:
    """Every variant's floor, measured on demand beside btcap's rounds (same conditions)."""

    def __init__(self, floors: dict[str, FloorRound]) -> None:
        self.floors = floors
        self.samples: dict[str, dict[int, list[float]]] = {v: {} for v in floors}
        self.cpu: dict[str, dict[int, list[float]]] = {v: {} for v in floors}

    async def measure(self, n: int, count: int) -> None:
        """``count`` rounds with ``n`` bidders on every variant."""
        for variant, floor in self.floors.items():
            samples = self.samples[variant].setdefault(n, [])
            cpu = self.cpu[variant].setdefault(n, [0.0, 0.0])
            await measure_floor(floor, n, count, samples, cpu)

    def results(self) -> tuple[dict[str, Any], dict[str, Any]]:
        """Wall ms (p50, p90, p99) and CPU ms per round (here, bidder processes) per
        variant and number of bidders."""
        wall = {v: {str(n): spread(s) for n, s in by_n.items()} for v, by_n in self.samples.items()}
        cpu = {
            v: {
                str(n): {
                    "this_process": c[0] / len(self.samples[v][n]) * 1e3,
                    "bidder_processes": c[1] / len(self.samples[v][n]) * 1e3,
                }
                for n, c in by_n.items()
            }
            for v, by_n in self.cpu.items()
        }
        return wall, cpu


@contextlib.asynccontextmanager
async def floor_reference(
    bidders: int, processes: int, curve: bool = False
) -> AsyncIterator[FloorReference]:
    """Every variant up at once (idle floors cost no CPU: they wait in poll)."""
    async with contextlib.AsyncExitStack() as stack:
        floors = {
            v: await stack.enter_async_context(floor_round(v, bidders, processes, curve))
            for v in VARIANTS
        }
        yield FloorReference(floors)


async def _alone(bidders: Sequence[int], count: int, processes: int) -> None:
    for curve in (False, True):
        async with floor_reference(max(bidders), processes, curve) as ref:
            for n in bidders:
                await ref.measure(n, count)
            wall, cpu = ref.results()
        for variant, rows in wall.items():
            for n, p in rows.items():
                c = cpu[variant][n]
                print(
                    f"{variant:>8}{' curve' if curve else ''} {n:>3} bidders: p50 {p['p50']:.3f}"
                    f" ms, p99 {p['p99']:.3f} ms, cpu {c['this_process']:.2f} + "
                    f"{c['bidder_processes']:.2f} ms a round"
                )


def main(argv: Sequence[str] | None = None) -> int:
    prog = "python -m btcap.bench.speed.auction_floor"
    parser = argparse.ArgumentParser(prog=prog, description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer rounds")
    args = parser.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f}")
    asyncio.run(_alone((1, 3, 10, 50), 200 if args.quick else 2000, 4))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
