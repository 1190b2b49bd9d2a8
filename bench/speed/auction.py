"""Auction round latency, remote capability tick round trip, and fail-over time.

- **round_ms**: one single-item auction round, ``await auctioneer.assign(task)`` from the
  call for bids to the accepted award, with 1, 3, 10 and 50 bidders: (a) every agent in
  this process on an :class:`~transports.InProcessNetwork` (codec on every hop); (b) over
  ZeroMQ tcp loopback with the bidders in up to :data:`PROCESSES` other OS processes (dealt
  round robin, each agent with its own actor system, socket and port). The rows for 1, 3
  and 10 bidders each run in a team of exactly those bidders and the origin: DESIGN's
  budget is a round with 10 bidders, and a deployment runs one robot per computer, so no
  robot pays for teammates it does not bid against. The 50 row runs in a team of 51; the
  same team's round with its first 10 bidders is its own row, ``10_of_51`` (a crowded
  host: 51 agents on a small machine pay 51 times the idle membership and ZMTP link
  heartbeats, 2,550 links pinged at both ends). The
  auction window is long (5 s), so a round that did not close early would show; the
  execution each round creates is cancelled at once so the next round finds the bidders
  free. ``early_close`` counts the rounds that closed because every invited bidder had
  answered. The tcp rounds run twice: plain (``zmq_tcp``), then with a CURVE key pair for
  every agent and the team's public keys as each one's allow-list (``zmq_tcp_curve``).
  Rounds run back to back; once the bidders' budget of calls from one auctioneer (#19: 256
  at once, then 64 a second; mirrored here) runs dry, the bench waits until it has room
  for :data:`~bench.speed.auction_rounds.BURST_ROUNDS` more, so no round waits out the
  window for a call left unanswered, and none is paced into a cold start.
  ``round_ms[...]["isolated"]``: rounds with 10 bidders one every :data:`ISOLATED_GAP_S`
  (every thread asleep in between), as an auction in a mission mostly is: waking them up
  is in that figure.
- **floor_ms**: the same round hand-written with no btcap (:mod:`bench.speed.auction_floor`:
  blocking pyzmq and an asyncio reader, the same process layout, messages of the same
  sizes), measured right before and after each tcp row, plain and CURVE: what no runtime
  can beat on this machine today. ``round_to_floor`` gives btcap's rows as a ratio to it.
- **round_cpu_ms**: CPU time per round (every thread, so ZeroMQ's I/O threads count) of
  this process and of the bidder processes during the bursts, minus what they burn idle
  (heartbeats, host trees; measured once the joins have settled): on a small shared
  machine it says more than wall time.
- **remote_tick_ms**, **failover_s**: see :mod:`bench.speed.auction_remote`.

Run ``python -m btcap.bench auction [--quick]`` or
``python -m btcap.bench.speed.auction [--quick]``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import tempfile
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from pathlib import Path
from typing import Any

from btcap.actors import configure_logging
from btcap.bench.common import percentiles, wait_until, write_result
from btcap.bench.cpumeter import CpuMeter
from btcap.bench.speed import transport as transport_bench
from btcap.bench.speed.auction_floor import FloorReference, floor_reference, spread
from btcap.bench.speed.auction_remote import bench_remote
from btcap.bench.speed.auction_report import table, to_floor
from btcap.bench.speed.auction_rounds import (
    BURST_ROUNDS,
    Figures,
    Plan,
    Reference,
    bidder_names,
    call_budget,
    rounds,
)
from btcap.team.demo import implementations
from btcap.team.deployment.launch import AgentSpec, spawn_agents
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork, KeyPair, TeamKeys, ZmqTransport
from btcap.transports.security import write_key_pair

__all__ = ["run"]

BIDDERS = (1, 3, 10, 50)
REFERENCE_BIDDERS = 10
CROWDED = "10_of_51"
"""The row of 10 bidders in the team of 51 (a crowded host)."""
TEAMS: tuple[tuple[int, tuple[tuple[str, int], ...]], ...] = (
    (1, (("1", 1),)),
    (3, (("3", 3),)),
    (10, (("10", 10),)),
    (50, ((CROWDED, 10), ("50", 50))),
)
"""Each team's bidders and the rows (label, bidders invited) measured in it."""
PROCESSES = 4
ISOLATED_GAP_S = 0.05
SETTLE_S = 3.0
"""After the last join: 51 agents exchange rosters for about 2 s (a burst of CPU that must
not count as idle, nor overlap the first rounds); a team of 11 in under 0.5 s."""
ASK_REFERENCE = 1000
"""tcp asks measured right before and after the 10-bidder rounds (plain tcp), each way."""
WINDOW_S = 5.0  # long, so an auction that did not close early would show
# Heartbeats every second, as a deployed team would run: with 51 agents on two cores, the
# default 0.1 s (all-to-all, 25 000 messages a second) would be most of what they do.
TEAM_TIMING: dict[str, Any] = {"heartbeat_s": 1.0, "failure_timeout_s": 5.0}
_LOCAL = "127.0.0.1"


def _origin_config() -> AgentConfig:
    return AgentConfig(auction_window_s=WINDOW_S, strategy="optimal", **TEAM_TIMING)


def _merge(into: Figures, part: Figures) -> None:
    for a, b in zip(into, part, strict=True):
        a.update(b)


async def _bench_inproc(plan: Plan) -> Figures:
    out: Figures = ({}, {}, {})
    for team, rows in TEAMS:
        _merge(out, await _inproc_team(team, rows, plan))
    return out


async def _inproc_team(team: int, rows: Sequence[tuple[str, int]], plan: Plan) -> Figures:
    reg = protocol_registry()
    net = InProcessNetwork(reg)
    names = bidder_names(team)
    agents = [
        Agent(
            name,
            transport=net.transport(name),
            registry=protocol_registry(),
            implementations=implementations(name, cost=1.0 + i),
            config=AgentConfig(**TEAM_TIMING),
        )
        for i, name in enumerate(names)
    ]
    origin = Agent(
        "origin", transport=net.transport("origin"), registry=reg, config=_origin_config()
    )
    started: list[Agent] = []
    try:
        for a in agents:
            await a.__aenter__()
            started.append(a)
        await origin.__aenter__()
        started.append(origin)
        await wait_until(lambda: set(names) <= origin.team.alive(), 20.0, "bidders joined")
        return await _all_sizes(origin, names, rows, plan, CpuMeter())
    finally:
        for a in reversed(started):
            await a.__aexit__(None, None, None)


async def _all_sizes(
    origin: Agent,
    names: Sequence[str],
    rows: Sequence[tuple[str, int]],
    plan: Plan,
    cpu: CpuMeter,
    reference: Reference | None = None,
) -> Figures:
    lat: dict[str, Any] = {}
    early: dict[str, Any] = {}
    cpu_ms: dict[str, Any] = {}
    warmup, count = plan.warmup, plan.rounds
    # a crowded team's roster burst must end before idle CPU is measured, quick or not
    settle, calm = (SETTLE_S, 2.0) if len(names) > 11 else (0.5, 0.5) if plan.quick else (1, 1)
    await asyncio.sleep(settle)  # let the joins settle
    await cpu.calibrate(calm)
    budget = call_budget()
    for label, n in rows:
        # Spread the bidders over every process (names were dealt round robin).
        await rounds(origin, names[:n], warmup, 0, budget)
        if reference is not None:
            await reference(label, n)  # right before and after: the same conditions
        cpu.start()
        samples, closed = await rounds(origin, names[:n], 0, count, budget, cpu)
        cpu_ms[label] = cpu.per_round_ms(count)
        if reference is not None:
            await reference(label, n)
        lat[label] = spread(samples)
        early[label] = {"rounds": count, "early": closed}
        if label == str(REFERENCE_BIDDERS):
            isolated, closed = await rounds(
                origin, names[:n], 0, max(20, count // 4), budget, gap_s=ISOLATED_GAP_S
            )
            lat["isolated"] = spread(isolated)
            early["isolated"] = {"rounds": len(isolated), "early": closed}
    return lat, early, cpu_ms


async def _bench_zmq(
    plan: Plan,
    floor: FloorReference,
    keys: Path | None = None,
    asks: dict[str, list[float]] | None = None,
) -> Figures:
    """Every team over tcp, each row with the floor measured right before and after it."""
    out: Figures = ({}, {}, {})
    async with contextlib.AsyncExitStack() as stack:
        ask = None if asks is None else await stack.enter_async_context(_asks(asks))

        async def reference(label: str, n: int) -> None:
            if label != CROWDED:  # the floor is not crowded: its row of 10 serves both
                await floor.measure(n, max(10, plan.rounds // 2))
            if ask is not None and label == str(REFERENCE_BIDDERS):
                await ask()

        for team, rows in TEAMS:
            _merge(out, await _zmq_team(team, rows, plan, reference, keys))
    return out


async def _zmq_team(
    team: int,
    rows: Sequence[tuple[str, int]],
    plan: Plan,
    reference: Reference,
    keys: Path | None,
) -> Figures:
    """A team over tcp; with ``keys`` (a directory of every agent's certificates, which is
    also the allow-list) every agent, the origin included, runs CURVE."""
    names = bidder_names(team)
    groups: list[list[AgentSpec]] = [[] for _ in range(min(PROCESSES, team))]
    for i, name in enumerate(names):
        spec = AgentSpec(
            robot=name,
            factory="btcap.team.demo:implementations",
            factory_args={"cost": 1.0 + i},
            config={**TEAM_TIMING},
            keys="" if keys is None else str(keys / f"{name}.key_secret"),
            trusted="" if keys is None else str(keys),
        )
        groups[i % len(groups)].append(spec)
    procs = spawn_agents(groups, timeout=60.0)
    try:
        peers = {robot: ep for p in procs for robot, ep in p.endpoints.items()}
        reg = protocol_registry()
        pair = None if keys is None else KeyPair.load(keys / "origin.key_secret")
        trusted = None if keys is None else TeamKeys.load(keys)
        transport = ZmqTransport(
            "origin", f"tcp://{_LOCAL}:*", reg, peers=peers, keys=pair, trusted=trusted
        )
        meter = CpuMeter([p.pid for p in procs])
        async with Agent("origin", transport=transport, registry=reg, config=_origin_config()) as o:
            await wait_until(lambda: set(names) <= o.team.alive(), 30.0, "bidders joined")
            return await _all_sizes(o, names, rows, plan, meter, reference)
    finally:
        for p in procs:
            p.stop()


@contextlib.asynccontextmanager
async def _asks(samples: dict[str, list[float]]) -> AsyncIterator[Callable[[], Awaitable[None]]]:
    """What an auction round is compared to, measured in the same run: a tcp ask of the
    runtime (to an echo actor in another process) and blocking pyzmq's round trip."""
    async with (
        transport_bench.zmq_tcp() as (ask, _),
        transport_bench.raw_zmq_tcp_blocking() as (floor, _),
    ):
        for i in range(ASK_REFERENCE):
            await ask(i)
            await floor(i)

        async def measure() -> None:
            for name, call in (("zmq_tcp_ask", ask), ("raw_zmq_tcp_blocking", floor)):
                await transport_bench.measure(call, ASK_REFERENCE, samples.setdefault(name, []))

        yield measure


def _team_keys(directory: Path, robots: Sequence[str]) -> Path:
    """A certificate pair per robot in ``directory``, which doubles as the allow-list
    (it holds every member's public ``NAME.key``)."""
    for robot in robots:
        write_key_pair(directory, robot)
    return directory


async def _run(quick: bool) -> dict[str, Any]:
    warmup, count = (10, 60) if quick else (30, 400)
    plan = Plan(warmup, count, quick)
    tick_warmup, ticks = (50, 300) if quick else (200, 3000)
    failovers = 2 if quick else 5
    load_before = os.getloadavg()[0]
    inproc, inproc_early, inproc_cpu = await _bench_inproc(plan)
    asks: dict[str, list[float]] = {}
    floor_ms: dict[str, Any] = {}
    floor_cpu: dict[str, Any] = {}
    async with floor_reference(max(BIDDERS), PROCESSES) as floor:
        zmq_tcp, zmq_early, zmq_cpu = await _bench_zmq(plan, floor, asks=asks)
        floor_ms["zmq_tcp"], floor_cpu["zmq_tcp"] = floor.results()
    with tempfile.TemporaryDirectory(prefix="btcap-bench-keys-") as tmp:
        keys = _team_keys(Path(tmp), ["origin", *bidder_names(max(BIDDERS))])
        async with floor_reference(max(BIDDERS), PROCESSES, curve=True) as floor:
            curve, curve_early, curve_cpu = await _bench_zmq(plan, floor, keys)
            floor_ms["zmq_tcp_curve"], floor_cpu["zmq_tcp_curve"] = floor.results()
    rtt, failover, info = await bench_remote(tick_warmup, ticks, failovers)
    all_early = all(
        v["early"] == v["rounds"]
        for e in (inproc_early, zmq_early, curve_early)
        for v in e.values()
    )
    ask_us = {name: percentiles(values) for name, values in asks.items()}
    k = str(REFERENCE_BIDDERS)
    rounds = {"zmq_tcp": zmq_tcp, "zmq_tcp_curve": curve}
    return {
        "round_ms": {"inproc": inproc, **rounds},
        "floor_ms": floor_ms,
        "floor_cpu_ms": floor_cpu,
        "round_to_floor": to_floor(rounds, floor_ms, CROWDED, k),
        "ask_us": ask_us,
        "round_to_ask": {
            "bidders": REFERENCE_BIDDERS,
            "round_p50_over_tcp_ask_p50": zmq_tcp[k]["p50"] * 1e3 / ask_us["zmq_tcp_ask"]["p50"],
            "round_p50_over_floor_p50": zmq_tcp[k]["p50"]
            * 1e3
            / ask_us["raw_zmq_tcp_blocking"]["p50"],
        },
        "round_cpu_ms": {"inproc": inproc_cpu, "zmq_tcp": zmq_cpu, "zmq_tcp_curve": curve_cpu},
        "early_close": {
            "inproc": inproc_early,
            "zmq_tcp": zmq_early,
            "zmq_tcp_curve": curve_early,
            "all": all_early,
        },
        "remote_tick_ms": percentiles(rtt),
        "failover_s": {
            "p50": percentiles(failover)["p50"],
            "max": max(failover),
            "repeats": len(failover),
            "samples": failover,
        },
        "setup": {
            "bidders": list(BIDDERS),
            "teams": {label: team + 1 for team, rows in TEAMS for label, _ in rows},
            "crowded_row": CROWDED,
            "rounds": count,
            "warmup_rounds": warmup,
            "window_s": WINDOW_S,
            "burst_rounds": BURST_ROUNDS,
            "isolated_gap_s": ISOLATED_GAP_S,
            "bidder_processes": PROCESSES,
            "remote_ticks": ticks,
            "failover": info,
            "load_average": [load_before, os.getloadavg()[0]],
            "quick": quick,
        },
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Measure, print a table, write ``bench/results/auction.json``."""
    configure_logging("error")  # the executors this benchmark kills are logged as lost
    data = asyncio.run(_run(quick))
    print(table(data, WINDOW_S))
    path = write_result("auction", data)
    print(f"wrote {path}")
    return data


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m btcap.bench.speed.auction", description=__doc__
    )
    parser.add_argument("--quick", action="store_true", help="fewer rounds, for CI smoke runs")
    args = parser.parse_args(argv)
    run(quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
