"""Hostile-input probe: bounded attacks from a raw pyzmq client against a team over tcp.

Two agents in this process over tcp loopback: ``origin`` ticks an Echo mission run by
``r1`` (the target) and keeps asking a probe actor on ``r1``. An attacker thread sends, one
attack at a time: a flood of hellos with distinct ids, big fake repository states for
invented robots, messages of unknown types, wrong schemas or nested 100,000 deep, and
an oversized frame.
Each check prints a PASS/FAIL line with its figures; :func:`run` returns False if one
failed (``python -m btcap.bench attacks [--quick]`` then exits non-zero). Verdicts are
counts (inputs refused or delivered, peers and files held afterwards, asks unanswered,
false failures), each waited for up to :data:`SETTLE_S`, never how fast: the machine's
load decides that, and the latencies are figures.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import gc
import os
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from typing import Any

import zmq

from btcap.actors import Actor, Address, handler
from btcap.bench.attacks.decode import probe_decode
from btcap.bench.attacks.echo import echo_mission
from btcap.bench.attacks.hostile import (
    Ping,
    Pong,
    dealer,
    fake_states,
    hello_flood,
    junk,
    oversized,
    registry,
)
from btcap.bench.attacks.member import probe_members
from btcap.bench.attacks.nodes import probe as node_actions
from btcap.bench.attacks.roles import probe_roles
from btcap.bench.attacks.silent import probe_silent
from btcap.bench.common import write_result
from btcap.bt.state import State
from btcap.team.core.members import TeamEvent
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.transports import ZmqTransport

__all__ = ["Counts", "probe", "run"]

_TCP = "tcp://127.0.0.1:*"
_DEAD = "tcp://127.0.0.1:9"  # discard port: where forged hellos say they live
ATTACKER = "mallory"
MAX_PEERS = 32
MAX_MESSAGE_BYTES = 1 << 20
STRANGER_TTL_S = 0.3  # r1 drops a peer that only said hello (teammates beat every 0.1 s)
FD_SLACK = 8  # open files allowed above the baseline once an attack is over
RSS_SLACK_MB = 64.0  # RSS growth allowed for the fake states (100 MB sent in full mode)
ASK_TIMEOUT_S = 3.0  # an ask unanswered this long (the team's lease) was not served
SETTLE_S = 30.0  # how long the target may take to drain an attack on a loaded machine
TICK_S = 0.01
#: Both robots share this process's loop with the probe, whose gc.collect() for the memory
#: figures can pause it for a good part of a second in a big process (the test suite):
#: a failure timeout and lease of a few seconds keep that pause from passing for an attack.
TEAM_CONFIG = AgentConfig(heartbeat_s=0.1, failure_timeout_s=3.0, lease_s=3.0, keepalive_s=0.5)
#: Probes of their own modules, each with its own team: ``(name, passed, figures)`` each.
MORE_PROBES = [
    node_actions,
    probe_roles,
    probe_members,
    probe_decode,
    probe_silent,
]


class _Echo(Actor):
    @handler
    def ping(self, msg: Ping) -> Pong:
        return Pong(msg.seq)


@dataclass(frozen=True)
class Counts:
    """How hard each attack pushes."""

    hellos: int
    states: int
    state_bytes: int
    junk: int

    @classmethod
    def of(cls, quick: bool) -> Counts:
        if quick:
            return cls(hellos=200, states=100, state_bytes=100_000, junk=2_000)
        return cls(hellos=2_000, states=1_000, state_bytes=100_000, junk=10_000)


@dataclass
class Check:
    name: str
    passed: bool
    figures: dict[str, Any]


@dataclass
class Health:
    """What the origin saw of the target while it was attacked."""

    failures: list[str] = field(default_factory=list)
    asks: list[float] = field(default_factory=list)
    ask_errors: int = 0
    ask_timeout_s: float = ASK_TIMEOUT_S


def open_files() -> int:
    return len(os.listdir("/proc/self/fd"))


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


# -- the team -------------------------------------------------------------------------------


@contextlib.asynccontextmanager
async def _team() -> AsyncIterator[tuple[Agent, Agent]]:
    reg_r1, reg_o = registry(), registry()
    t1 = ZmqTransport(
        "r1",
        _TCP,
        reg_r1,
        max_peers=MAX_PEERS,
        max_message_bytes=MAX_MESSAGE_BYTES,
        stranger_ttl_s=STRANGER_TTL_S,
    )
    to = ZmqTransport("origin", _TCP, reg_o, peers={"r1": t1.endpoint}, max_peers=MAX_PEERS)
    r1 = Agent(
        "r1",
        transport=t1,
        registry=reg_r1,
        implementations=implementations("r1"),
        actors={"probe": _Echo()},
        config=TEAM_CONFIG,
    )
    origin = Agent("origin", transport=to, registry=reg_o, config=TEAM_CONFIG)
    async with r1, origin:
        yield r1, origin


async def _until(cond: Callable[[], bool], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError("team did not get ready")
        await asyncio.sleep(TICK_S)


async def _ask_loop(origin: Agent, health: Health, stop: asyncio.Event) -> None:
    seq = 0
    while not stop.is_set():
        seq += 1
        t0 = time.perf_counter()
        try:
            await origin.system.ask(Address("r1", "probe"), Ping(seq), timeout=health.ask_timeout_s)
        except Exception:
            health.ask_errors += 1
        health.asks.append(time.perf_counter() - t0)
        await asyncio.sleep(0.05)


async def _attack(
    name: str,
    fn: Callable[[], None],
    r1: Agent,
    health: Health,
    drained: Callable[[dict[str, int]], bool] = lambda _: True,
) -> dict[str, Any]:
    """Run one attack to the end, let the target drain (until ``drained`` says so of the
    counters that moved and the files opened are closed again, up to :data:`SETTLE_S`),
    and return before/after figures."""
    t1 = _zmq(r1)
    gc.collect()
    stats_before = _counters(r1)
    before = {"fds": open_files(), "rss_mb": rss_mb(), "peers": len(t1.peers())}
    asks_before, failures_before = len(health.asks), len(health.failures)
    errors_before = health.ask_errors
    t0 = time.perf_counter()
    await asyncio.to_thread(fn)
    sent_s = time.perf_counter() - t0
    peak_rss = rss_mb()
    await asyncio.sleep(0.5)  # the target drains what is queued; lingering sockets close

    def moved() -> dict[str, int]:
        return {k: v - stats_before.get(k, 0) for k, v in _counters(r1).items()}

    settled = await _eventually(
        lambda: drained(moved()) and open_files() <= before["fds"] + FD_SLACK, SETTLE_S
    )
    drain_s = time.perf_counter() - t0 - sent_s
    gc.collect()
    during = health.asks[asks_before:]
    return {
        "attack": name,
        "sent_s": round(sent_s, 3),
        "fds_before": before["fds"],
        "fds_after": open_files(),
        "rss_before_mb": round(before["rss_mb"], 1),
        "rss_peak_mb": round(peak_rss, 1),
        "rss_after_mb": round(rss_mb(), 1),
        "peers_before": before["peers"],
        "peers_after": len(t1.peers()),
        "drained": settled,
        "drain_s": round(drain_s, 3),
        "ask_max_ms": round(1000 * max(during, default=0.0), 1),
        "asks": len(during),
        "ask_errors": health.ask_errors - errors_before,
        "false_failures": health.failures[failures_before:],
        "stats": moved(),
    }


async def _eventually(cond: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            return False
        await asyncio.sleep(TICK_S)
    return True


def _zmq(agent: Agent) -> ZmqTransport:
    t = agent.system.transport
    assert isinstance(t, ZmqTransport)
    return t


def _counters(agent: Agent) -> dict[str, int]:
    """The target's transport and runtime counters, drop reasons flattened in."""
    t = _zmq(agent)
    stats = dataclasses.asdict(t.stats)
    reasons = stats.pop("by_reason")
    stats.pop("refused_by")  # who refused the target's handshakes: no counter
    return {
        **stats,
        **{f"dropped:{k}": v for k, v in reasons.items()},
        "disconnects": t.disconnects,
        "dead_letters": agent.system.stats.dead_letters,
        "team_refused": agent.team.refused,
        **{f"system:{k}": v for k, v in agent.system.stats.dropped.items()},
    }


async def _latecomer(endpoint: str, r1: Agent) -> bool:
    """Does a robot that says hello after the flood still become a peer of the target?"""
    ctx: zmq.Context[Any] = zmq.Context()
    try:
        with dealer(ctx, "latecomer", endpoint):
            return await _eventually(lambda: "latecomer" in _zmq(r1).peers(), SETTLE_S)
    finally:
        ctx.term()


def _healthy(f: dict[str, Any]) -> bool:
    """The origin kept the target and had every ask answered (how fast is a figure)."""
    return not f["false_failures"] and f["ask_errors"] == 0 and f["drained"]


async def probe(quick: bool, *, more: bool = True) -> list[Check]:
    """Run the attacks against a fresh team; one :class:`Check` per attack plus the mission
    (and, with ``more``, the :data:`MORE_PROBES`, each on a team of its own)."""
    counts = Counts.of(quick)
    health = Health()
    checks: list[Check] = []
    async with _team() as (r1, origin):
        await _until(lambda: "r1" in origin.repository.providers(ECHO.identity), 10.0)
        origin.team.subscribe(
            lambda event, robot: (
                health.failures.append(f"{event.value}:{robot}")
                if event in (TeamEvent.FAILED, TeamEvent.LEFT)
                else None
            )
        )
        stop = asyncio.Event()
        async with echo_mission(origin, TICK_S) as echo:
            node, tree = echo.node, echo.tree
            asking = asyncio.create_task(_ask_loop(origin, health, stop))
            try:
                running = State.RUNNING
                await _until(lambda: node.state is running and node.outputs["value"] == 1, 10.0)
                endpoint = _zmq(r1).endpoint
                team_before = dict(r1.repository.team)

                f = await _attack(
                    "fake_states",
                    lambda: fake_states(endpoint, counts.states, counts.state_bytes),
                    r1,
                    health,
                )
                f["team_unchanged"] = r1.repository.team == team_before
                ok = f["team_unchanged"] and f["rss_after_mb"] - f["rss_before_mb"] <= RSS_SLACK_MB
                ok = ok and f["stats"]["received"] >= counts.states  # reached the repository
                checks.append(Check("fake_states", ok and _healthy(f), f))

                def all_junk(moved: dict[str, int]) -> bool:
                    return moved["malformed"] + moved["received"] >= counts.junk

                f = await _attack("junk", lambda: junk(endpoint, counts.junk), r1, health, all_junk)
                checks.append(Check("junk", all_junk(f["stats"]) and _healthy(f), f))

                f = await _attack(
                    "oversized",
                    lambda: oversized(endpoint, 2 * MAX_MESSAGE_BYTES),
                    r1,
                    health,
                    lambda moved: moved["disconnects"] >= 1,
                )
                # Cut off by libzmq before the decoder saw it (it would count as malformed).
                ok = f["stats"]["disconnects"] >= 1 and f["stats"]["malformed"] == 0
                checks.append(Check("oversized", ok and _healthy(f), f))

                f = await _attack(
                    "hello_flood",
                    lambda: hello_flood(endpoint, counts.hellos),
                    r1,
                    health,
                    lambda _: len(_zmq(r1).peers()) <= MAX_PEERS,
                )
                f["latecomer_accepted"] = await _latecomer(endpoint, r1)
                ok = f["peers_after"] <= MAX_PEERS and f["fds_after"] <= f["fds_before"] + FD_SLACK
                ok = ok and f["latecomer_accepted"]
                checks.append(Check("hello_flood", ok and _healthy(f), f))

                node.set_input("value", 2)
                await _until(lambda: node.outputs["value"] == 2, SETTLE_S)
                node.set_input("stop", True)
                await _until(lambda: tree.root.state is State.SUCCEEDED, SETTLE_S)
            except TimeoutError:
                pass
            finally:
                stop.set()
                await asking
        mission = {
            "state": tree.root.state.name,
            "assignments": list(node.assignments),
            "false_failures": health.failures,
            "ask_errors": health.ask_errors,
            "asks": len(health.asks),
            "ask_max_ms": round(1000 * max(health.asks, default=0.0), 1),
        }
        ok = (
            tree.root.state is State.SUCCEEDED
            and node.assignments == ["r1"]
            and not health.failures
            and health.ask_errors == 0
        )
        checks.append(Check("mission", ok, mission))
    for extra in MORE_PROBES if more else []:
        checks += [Check(name, passed, figures) for name, passed, figures in await extra(quick)]
    return checks


def _line(check: Check) -> str:
    """``PASS name: key=value ...``: the figures, then the counters that moved."""
    f = check.figures
    shown = " ".join(f"{k}={v}" for k, v in f.items() if k not in ("attack", "stats"))
    shown += "".join(f" {k}={v}" for k, v in f.get("stats", {}).items() if v)
    return f"{'PASS' if check.passed else 'FAIL'} {check.name}: {shown}"


def run(quick: bool = False) -> bool:
    """Run the probe, print a line per check, write ``attacks.json``; True if all passed."""
    t0 = time.perf_counter()
    checks = asyncio.run(probe(quick))
    for check in checks:
        print(_line(check), flush=True)
    passed = all(c.passed for c in checks)
    path = write_result(
        "attacks",
        {
            "quick": quick,
            "counts": dataclasses.asdict(Counts.of(quick)),
            "passed": passed,
            "seconds": round(time.perf_counter() - t0, 2),
            "checks": {c.name: {"passed": c.passed, **c.figures} for c in checks},
        },
    )
    print(f"{'PASS' if passed else 'FAIL'} attacks: {path}", flush=True)
    return passed
