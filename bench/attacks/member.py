"""Attacks by a member acting in its own name, and a keyless Sybil (issue 19, item 5).

A keyless team over tcp loopback in this process: ``origin``, robots ``r1`` and ``r2``
(both run Echo) and ``mallory``, a member like any other. Mallory:

- ``award``: awards r1 an execution no auction preceded, with a 10^6 s lease;
- ``lease``: calls for bids like an auctioneer, then awards r1 with a 10^6 s lease;
- ``heartbeat_churn``: 300 heartbeats in 3 s to the origin, its busy flag flipped in
  each, while the origin's mission runs on r1 (every "came free" is news);
- ``sybil``: a raw pyzmq client makes up ghost members (a hello from a dead endpoint,
  a big capability list each, then a heartbeat a period for :data:`BEAT_S`) that then
  fall silent; twice over, with the library's default timing: every ghost must be
  forgotten, the agent must give its heap back after each flood (a trim of its own, a
  count), nothing of a flood may stay live, no robot falsely failed. RSS is reported as
  the agent left it and judged after a trim by the bench: what glibc still keeps free
  at that moment depends on when threads let buffers go (on a loaded machine, after
  the agent's trim: 55 and 71 MB against 48 measured), what stays live does not.

Each gives ``(name, passed, figures)``; :func:`probe_members` is one of the attack
probe's ``MORE_PROBES`` (``python -m btcap.bench attacks``).
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import os
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

import zmq

from btcap.actors import Address, Message
from btcap.actors.heap import HeapTrim, malloc_trim
from btcap.bench.attacks.echo import echo_mission, until
from btcap.bt.state import State
from btcap.team.core.members import TeamEvent
from btcap.team.demo import ECHO, implementations
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Award,
    AwardReply,
    CallForBids,
    CancelExecution,
    Heartbeat,
    RepositoryState,
)
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport
from btcap.transports.codec import Codec, Envelope, Kind

__all__ = ["probe_members", "probe_own_name", "probe_sybil"]

_TCP = "tcp://127.0.0.1:*"
_DEAD = "tcp://127.0.0.1:9"  # discard port: where the ghosts say they live
MC = "mission_control"
HUGE_LEASE_S = 1e6
#: As the attack probe's team: a failure timeout of a few seconds rides out gc pauses.
CONFIG = AgentConfig(heartbeat_s=0.1, failure_timeout_s=3.0, lease_s=3.0, keepalive_s=0.5)
CHURN_BEATS = 300
CHURN_S = 3.0
CHURN_MAX_AUCTIONS = 15  # a burst of news, then one per auction window (1 s)
FD_SLACK = 16
RSS_SLACK_MB = 40.0  #: live RSS (after a trim) allowed above the baseline after the first flood
#: Live RSS each further flood may add over the highest level before it (a flood's
#: state kept, untrimmed: 40-100 MB). Over the previous flood alone would judge noise:
#: in a suite's long-lived process live RSS moves by 6-20 MB between measurements.
REPEAT_SLACK_MB = 16.0
BEAT_S = 5.0  #: how long each ghost beats before it falls silent
FLOODS = 2
#: The library's default timing (failure_timeout_s 0.5 s, lease 1 s): no false failure.
SYBIL_CONFIG = AgentConfig()
CPU_SLACK = 0.05  # idle CPU (share of one core) allowed above the baseline afterwards

Result = tuple[str, bool, dict[str, Any]]


def _open_files() -> int:
    return len(os.listdir("/proc/self/fd"))


def _held_bytes(state: RepositoryState) -> int:
    """The characters of a teammate's capability list a robot holds."""
    return sum(len(k) + len(v) for k, v in state.interfaces.items()) + sum(
        map(len, state.succeeded)
    )


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


async def _idle_cpu(seconds: float) -> float:
    """This process's CPU time over ``seconds`` of wall time, as a share of one core."""
    c0, t0 = time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    return (time.process_time() - c0) / (time.perf_counter() - t0)


async def _live_rss_mb() -> float:
    """RSS once the free heap is given back: what is still in use, whenever threads
    freed their buffers (the trim blocks: off the loop)."""
    await asyncio.to_thread(malloc_trim)
    return _rss_mb()


def _trimmed_since(heap: HeapTrim, trims: int) -> Callable[[], bool]:
    """Whether the agent trimmed its heap since it had run ``trims`` trims."""
    return lambda: heap.trims > trims


@contextlib.asynccontextmanager
async def _team(config: AgentConfig = CONFIG) -> AsyncIterator[dict[str, Agent]]:
    """origin, r1, r2 and mallory on keyless tcp loopback, transports as deployed."""
    names = ("r1", "r2", "origin", "mallory")
    transports: dict[str, ZmqTransport] = {}
    regs = {n: protocol_registry() for n in names}
    for n in names:
        seeds = {} if n == "r1" else {"r1": transports["r1"].endpoint}
        transports[n] = ZmqTransport(n, _TCP, regs[n], peers=seeds)
    agents = {
        n: Agent(
            n,
            transport=transports[n],
            registry=regs[n],
            implementations=implementations(n) if n in ("r1", "r2") else (),
            config=config,
        )
        for n in names
    }
    try:
        async with contextlib.AsyncExitStack() as stack:
            for n in names:
                await stack.enter_async_context(agents[n])
            origin = agents["origin"]
            ok = await until(
                lambda: (
                    {"r1", "r2"} <= origin.repository.providers(ECHO.identity)
                    and set(names) - {"origin"} <= set(origin.team.members)
                    and {"origin", "mallory"} <= set(agents["r1"].team.members)
                ),
                15.0,
            )
            if not ok:
                raise TimeoutError("the team did not form")
            yield agents
    finally:
        for t in transports.values():
            t.close()


def _echo_award(auction: AuctionId, number: int, lease_s: float) -> Award:
    execution = ExecutionId("mallory", "root/echo", number)
    return Award(auction, execution, "Echo", "echo-r1", {"value": 1}, lease_s)


async def _award_from_mallory(team: dict[str, Agent], award: Award) -> AwardReply:
    mallory, r1 = team["mallory"], team["r1"]
    ref = mallory.system.ref(Address("r1", MC))
    reply = await ref.ask(award, expect=AwardReply, timeout=2.0)
    if reply.accepted:  # measured: give the robot back for the next case
        mallory.system.tell(Address("r1", MC), CancelExecution(award.execution, "probe done"))
        await until(lambda: r1.mission_control.body.idle, 2.0)
    return reply


async def _award(team: dict[str, Agent]) -> Result:
    """Awards no auction preceded, each with a 10^6 s lease."""
    accepted, reasons = 0, set()
    for n in range(1, 6):
        reply = await _award_from_mallory(team, _echo_award(AuctionId("mallory", n), n, 1e6))
        accepted += reply.accepted
        reasons.add(reply.reason[:80])
    figures = {"awards_sent": 5, "awards_accepted": accepted, "reasons": sorted(reasons)}
    return "award", accepted == 0, figures


async def _lease(team: dict[str, Agent]) -> Result:
    """A real call for bids from mallory (r1 bids), then its award with a 10^6 s lease."""
    auction = AuctionId("mallory", 1000)
    cfb = CallForBids(auction, "Echo", ECHO.identity, {"value": 1})
    team["mallory"].system.tell(Address("r1", MC), cfb)
    await asyncio.sleep(0.1)
    reply = await _award_from_mallory(team, _echo_award(auction, 1000, HUGE_LEASE_S))
    figures = {"lease_s": HUGE_LEASE_S, "accepted": reply.accepted, "reason": reply.reason}
    return "lease", not reply.accepted and "max_lease_s" in reply.reason, figures


async def _churn(team: dict[str, Agent]) -> Result:
    """300 heartbeats in 3 s with a flipped busy flag, while the origin's work runs."""
    origin, mallory = team["origin"], team["mallory"]
    async with echo_mission(origin, tick_s=0.02, shutdown=True) as mission:
        node = mission.node
        if not await until(lambda: node.state is State.RUNNING, 10.0):
            return "heartbeat_churn", False, {"error": "the mission did not start"}
        auctions = origin.allocator.stats.auctions
        t = mallory.team
        beat = t.beat + 1_000_000
        for k in range(CHURN_BEATS):
            hb = Heartbeat("mallory", t.incarnation, mallory.repository.version, k % 2 == 0)
            mallory.system.tell(Address("origin", "team"), _beat(hb, beat + k))
            await asyncio.sleep(CHURN_S / CHURN_BEATS)
        await asyncio.sleep(1.0)  # re-evaluations under way finish
        held = origin.allocator.stats.auctions - auctions
        figures = {
            "heartbeats": CHURN_BEATS,
            "seconds": CHURN_S,
            "reevaluation_auctions": held,
            "news_ignored": getattr(origin.mission_control.stats, "news_ignored", 0),
            "assignments": list(node.assignments),
        }
        return "heartbeat_churn", held <= CHURN_MAX_AUCTIONS, figures


def _beat(hb: Heartbeat, beat: int) -> Heartbeat:
    return Heartbeat(hb.robot, hb.incarnation, hb.repo_version, hb.busy, beat)


def _frame(codec: Codec, sender: str, to: str, path: str, msg: Message) -> bytes:
    return b"M" + codec.encode(Envelope(Kind.TELL, Address(sender, "x"), Address(to, path), msg))


def _ghosts(endpoint: str, n: int, state_bytes: int, beat_s: float = BEAT_S) -> None:
    """Made-up members: a hello from a dead endpoint and a big capability list each, then
    a heartbeat each a period (each its own probe) for ``beat_s``, then silence."""
    codec = Codec(protocol_registry())
    filler = "i" * 1000
    interfaces = {f"Iface{k}": filler for k in range(state_bytes // 1000)}
    ctx: zmq.Context[Any] = zmq.Context()
    socks: list[tuple[str, zmq.Socket[bytes]]] = []
    try:
        for i in range(n):
            ghost = f"ghost-{i}"
            sock = ctx.socket(zmq.DEALER)
            sock.setsockopt(zmq.ROUTING_ID, ghost.encode())
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.SNDHWM, 0)
            sock.connect(endpoint)
            sock.send(b"H" + _DEAD.encode())
            sock.send(
                _frame(codec, ghost, "r1", "repository", RepositoryState(ghost, 1, interfaces))
            )
            socks.append((ghost, sock))
        period = SYBIL_CONFIG.heartbeat_s
        t0 = time.monotonic()
        beat = 0
        while time.monotonic() - t0 < beat_s:
            beat += 1
            for ghost, sock in socks:
                hb = Heartbeat(ghost, 1, 1, False, beat, probe=beat)
                sock.send(_frame(codec, ghost, "r1", "team", hb))
            time.sleep(max(0.0, t0 + beat * period - time.monotonic()))
        time.sleep(0.5)  # the last beats leave before the sockets close
    finally:
        for _, sock in socks:
            sock.close(0)
        ctx.term()


async def _sybil(quick: bool, ghosts: int | None = None) -> Result:
    n, size = (200, 300_000) if quick else (1000, 900_000)
    n = ghosts or n
    async with _team(SYBIL_CONFIG) as team:
        r1, origin = team["r1"], team["origin"]
        false_failures: list[str] = []

        def watch(me: str) -> Callable[[TeamEvent, str], None]:
            def seen(event: TeamEvent, robot: str) -> None:
                if event is TeamEvent.FAILED and robot in team:
                    false_failures.append(f"{me} saw {robot} fail")

            return seen

        for name, agent in team.items():
            agent.team.subscribe(watch(name))
        joins: list[str] = []
        r1.team.subscribe(lambda e, r: joins.append(r) if e is TeamEvent.JOINED else None)
        held_peak = 0
        gc.collect()
        fds0, rss0 = _open_files(), await _live_rss_mb()
        cpu0 = await _idle_cpu(1.0)
        floods: list[dict[str, Any]] = []
        swim, heap = r1.team.swim, r1.team.heap
        for _ in range(FLOODS):
            joins.clear()
            forgotten, trims = swim.forgotten, heap.trims
            sending = asyncio.create_task(
                asyncio.to_thread(_ghosts, r1.system.transport.endpoint, n, size)  # type: ignore[union-attr]
            )
            peak_fds, peak_rss = 0, 0.0
            while not sending.done():
                cost = sum(_held_bytes(st) for st in r1.repository.team.values())
                held_peak = max(held_peak, cost)
                peak_fds, peak_rss = max(peak_fds, _open_files()), max(peak_rss, _rss_mb())
                await asyncio.sleep(0.05)
            await sending
            # Silent now. Each is forgotten once silent for SwimParams.forget_s (never
            # confirmed: it answered no probe): the bound, from the last beat, plus slack.
            bound = swim.params.forget_s(n + len(team)) + 2 * swim.params.period_s + 5.0
            t0 = time.monotonic()
            await until(lambda: not any(m.startswith("ghost-") for m in r1.team.members), bound)
            gone_s = time.monotonic() - t0
            # The burst is over: the agent trims its heap (an event, awaited; its timer
            # waits HeapTrim.every_s at most), then the trim's thread runs.
            trimmed = await until(_trimmed_since(heap, trims), heap.every_s + bound)
            await asyncio.sleep(1.0)
            gc.collect()
            rss_left = _rss_mb()
            floods.append(
                {
                    "ghosts_joined": sum(r.startswith("ghost-") for r in joins),
                    "ghosts_left": sum(m.startswith("ghost-") for m in r1.team.members),
                    "forgotten": swim.forgotten - forgotten,
                    "forgotten_within_s": round(gone_s, 1),
                    "fds_peak": peak_fds,
                    "rss_peak_mb": round(peak_rss, 1),
                    "rss_after_mb": round(rss_left, 1),
                    "rss_live_mb": round(await _live_rss_mb(), 1),
                    "heap_trimmed": trimmed,
                    "heap_trims": heap.trims,
                }
            )
        fds1, rss1 = _open_files(), floods[-1]["rss_live_mb"]
        cpu1 = await _idle_cpu(2.0)
        t1 = r1.system.transport
        to = origin.system.transport
        figures = {
            "ghosts": n,
            "state_bytes": size,
            "beat_s": BEAT_S,
            "floods": floods,
            "capability_lists_held_peak_mb": round(held_peak / 2**20, 1),
            "fds_before": fds0,
            "fds_after": fds1,
            "rss_live_before_mb": round(rss0, 1),
            "rss_live_after_mb": round(rss1, 1),
            "idle_cpu_before": round(cpu0, 3),
            "idle_cpu_after": round(cpu1, 3),
            "r1_peers_after": len(t1.peers()) if t1 is not None else -1,
            "origin_peers_after": len(to.peers()) if to is not None else -1,
            "false_failures": false_failures,
        }
        levels = [rss0, *(f["rss_live_mb"] for f in floods)]
        ok = (
            all(f["ghosts_left"] == 0 and f["heap_trimmed"] for f in floods)
            and floods[0]["rss_live_mb"] - rss0 <= RSS_SLACK_MB
            and all(  # over the highest level before it: the baseline itself moves
                b - max(levels[:i]) <= REPEAT_SLACK_MB for i, b in enumerate(levels) if i >= 2
            )
            and fds1 <= fds0 + FD_SLACK
            and cpu1 <= cpu0 + CPU_SLACK
            and not false_failures
        )
        return "sybil", ok, figures


async def probe_own_name(quick: bool) -> list[Result]:
    """What a member may do in its own name: awards, leases, heartbeat churn (one team)."""
    async with _team() as team:
        return [await _award(team), await _lease(team), await _churn(team)]


async def probe_sybil(quick: bool, ghosts: int | None = None) -> list[Result]:
    """A keyless Sybil on a fresh team (``ghosts`` made-up members instead of the mode's)."""
    return [await _sybil(quick, ghosts)]


async def probe_members(quick: bool) -> list[Result]:
    """The member and Sybil attacks, each on a fresh team."""
    return await probe_own_name(quick) + await probe_sybil(quick)
