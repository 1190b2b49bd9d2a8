"""Attack probe, decoding cost: valid messages whose free-form fields hold small nested
containers, millions of objects for the receiver to build unless it screens first.

Two teams over tcp loopback in this process, each an ``origin`` that ticks an Echo
mission run by ``r1`` (the target) and keeps asking a probe actor on ``r1``:

- keyed: ``eye``, an observer key, sends calls for bids whose ``inputs`` are thousands
  of lists 100 deep (3.5 MB in full mode): refused for its role, before decoding;
- keyless: ``mallory``, any local process under a made-up name, sends the same (too big
  for a non-member) and a smaller nested one (within that size, too nested); then a
  member (the origin's own link) sends the big one and consensus tasks with nested
  inputs: too nested, whoever sends them.

Every frame must be refused and counted, with no teammate declared failed and every ask
answered. Figures per attack: the target's CPU per frame (the loop thread's, less what
it used idle), the slowest ask while attacked. Frames are encoded before the clock runs.
Hooked into :mod:`btcap.bench.attacks.probe` (``python -m btcap.bench attacks``).
"""

from __future__ import annotations

import asyncio
import contextlib
import tempfile
import time
from collections.abc import AsyncIterator, Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zmq

from btcap.actors import Actor, Address, Message, handler
from btcap.bench.attacks.echo import echo_mission, echo_team, until
from btcap.bench.attacks.hostile import Ping, Pong, registry
from btcap.bt.state import State
from btcap.team.core.members import TeamEvent
from btcap.team.demo import ECHO
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.membership.roles import role_table
from btcap.team.messages import CallForBids, ConsensusTasks, OpenTask
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.transports import ZmqTransport
from btcap.transports.codec import Codec, Envelope, Kind
from btcap.transports.security import write_key_pair

__all__ = ["Attack", "frames", "probe_decode"]

_TCP = "tcp://127.0.0.1:*"
_CONFIG = AgentConfig(heartbeat_s=0.1, failure_timeout_s=3.0, lease_s=3.0, keepalive_s=0.5)
_KEYS = {"r1": "robot", "origin": "robot", "eye": "observer"}  # robots: origin asks
ASK_TIMEOUT_S = 4.0
"""An ask not answered this soon is an error: what only a stalled target causes."""
FRAMES = 10
MARK = 990_099
"""The auction number and task version of the attack's messages: one taken is seen."""
Result = tuple[str, bool, dict[str, Any]]


@dataclass(frozen=True)
class Attack:
    """``frames`` of one shape, from ``sender``, each refused under ``reason``; a stranger
    says ``hello`` first (the target drops one that fell silent)."""

    name: str
    sender: str
    frames: list[bytes]
    reason: str
    hello: bytes | None = None


def _nest(depth: int) -> Any:
    value: Any = 0
    for _ in range(depth):
        value = [value]
    return value


def frames(codec: Codec, sender: str, quick: bool) -> dict[str, list[bytes]]:
    """The shapes, as frames from ``sender`` to r1 (``M`` + envelope)."""
    lists = 9_000 if quick else 36_000  # 0.9 / 3.6 MB: lists 100 deep
    auction = AuctionId(sender, MARK)

    def frame(path: str, msg: Message) -> bytes:
        env = Envelope(Kind.TELL, Address(sender, "x"), Address("r1", path), msg)
        return b"M" + codec.encode(env)

    deep = [_nest(100) for _ in range(lists)]
    call = frame("mission", CallForBids(auction, ECHO.name, ECHO.identity, {"value": deep}))
    small = [_nest(100) for _ in range(2_400)]  # 240 KB: within a non-member's size
    call_small = frame("mission", CallForBids(auction, ECHO.name, ECHO.identity, {"v": small}))
    tasks = [
        OpenTask(ExecutionId(sender, f"n{i}", i), ECHO.name, ECHO.identity, {"v": _nest(8)}, ["r1"])
        for i in range(5_000 if quick else 20_000)
    ]
    offer = frame("consensus", ConsensusTasks(sender, MARK, tasks))
    return {"calls": [call] * FRAMES, "calls_small": [call_small] * FRAMES, "tasks": [offer] * 3}


class _Echo(Actor):
    @handler
    def ping(self, msg: Ping) -> Pong:
        return Pong(msg.seq)


@dataclass
class _Watch:
    failures: list[str] = field(default_factory=list)
    asks: list[float] = field(default_factory=list)
    ask_errors: int = 0
    #: How late the loop woke a 10 ms sleep: a stall, whatever else is slow.
    lags: list[float] = field(default_factory=list)


def _failures(me: str, into: list[str]) -> Callable[[TeamEvent, str], None]:
    def heard(event: TeamEvent, who: str) -> None:
        if event in (TeamEvent.FAILED, TeamEvent.LEFT):
            into.append(f"{me} saw {event.value}:{who}")

    return heard


@contextlib.asynccontextmanager
async def _team(keys: Path | None) -> AsyncIterator[tuple[Agent, Agent, _Watch, ZmqTransport]]:
    """r1 and origin running an Echo mission, origin asking r1 every 50 ms; yields the
    agents, what origin saw, and r1's transport."""

    def transport(name: str) -> ZmqTransport:
        if keys is None:
            return ZmqTransport(name, _TCP, registry())
        return ZmqTransport(name, _TCP, registry(), keys=keys / f"{name}.key_secret", trusted=keys)

    t1, to = transport("r1"), transport("origin")
    watch = _Watch()
    async with echo_team(t1, to, _CONFIG, {"probe": _Echo()}) as (r1, origin):
        for agent in (r1, origin):
            agent.team.subscribe(_failures(agent.robot, watch.failures))
        await until(lambda: "r1" in origin.repository.providers(ECHO.identity), 10.0)
        stop = asyncio.Event()

        async def ask() -> None:
            # Timed from when it was due, not sent: a loop stalled between two asks shows.
            seq, due = 0, time.perf_counter()
            while not stop.is_set():
                seq += 1
                try:
                    await origin.system.ask(
                        Address("r1", "probe"), Ping(seq), timeout=ASK_TIMEOUT_S
                    )
                except Exception:
                    watch.ask_errors += 1
                watch.asks.append(time.perf_counter() - due)
                due = time.perf_counter() + 0.05
                await asyncio.sleep(0.05)

        async def lag() -> None:
            while not stop.is_set():
                t0 = time.perf_counter()
                await asyncio.sleep(0.01)
                watch.lags.append(time.perf_counter() - t0 - 0.01)

        async with echo_mission(origin) as mission:
            background = [asyncio.create_task(f()) for f in (ask, lag)]
            try:
                await until(lambda: mission.node.state is State.RUNNING, 10.0)
                yield r1, origin, watch, t1
            finally:
                stop.set()
                await asyncio.gather(*background, return_exceptions=True)


def _marked(msg: CallForBids | ConsensusTasks) -> bool:
    return (msg.auction.number if isinstance(msg, CallForBids) else msg.version) == MARK


def _send_all(sock: zmq.Socket[Any], out: list[bytes]) -> None:
    for f in out:
        sock.send(f, copy=False)


async def _strike(attack: Attack, sock: zmq.Socket[Any], r1: ZmqTransport, watch: _Watch) -> Result:
    """Send ``attack``'s frames at once; wait until r1 refused each (or 120 s)."""
    counted = r1.stats.by_reason
    before = counted.get(attack.reason, 0)
    stats0 = dict(counted)
    idle0, wall0 = time.thread_time(), time.perf_counter()
    await asyncio.sleep(0.5)  # what the loop costs without the attack (frames made before)
    idle = (time.thread_time() - idle0) / (time.perf_counter() - wall0)
    asks, lags, failures = len(watch.asks), len(watch.lags), len(watch.failures)
    taken = [0]  # frames that reached r1's actors (none may)
    inner = r1._deliver
    assert inner is not None

    def deliver(env: Envelope) -> None:
        msg = env.msg
        if isinstance(msg, CallForBids | ConsensusTasks) and _marked(msg):
            taken[0] += 1
        inner(env)

    r1._deliver = deliver
    cpu0, wall0 = time.thread_time(), time.perf_counter()
    if attack.hello is None:  # a transport's own link: sent from the loop that owns it
        _send_all(sock, attack.frames)
    else:  # the attacker's own socket, from its own thread
        await asyncio.to_thread(_send_all, sock, [attack.hello, *attack.frames])
    n = len(attack.frames)
    done = await until(lambda: counted.get(attack.reason, 0) - before + taken[0] >= n, 120.0)
    cpu = time.thread_time() - cpu0 - idle * (time.perf_counter() - wall0)
    r1._deliver = inner
    await asyncio.sleep(0.3)  # a late stall still shows in the asks
    during = watch.asks[asks:]
    refused = counted.get(attack.reason, 0) - before
    figures = {
        "sender": attack.sender,
        "frames": n,
        "frame_mb": round(len(attack.frames[0]) / 1e6, 2),
        "refused": refused,
        "taken": taken[0],
        "reason": attack.reason,
        "cpu_ms_per_frame": round(1000 * max(cpu, 0.0) / n, 2),
        "ask_max_ms": round(1000 * max(during, default=0.0), 1),
        "asks": len(during),
        "loop_lag_max_ms": round(1000 * max(watch.lags[lags:], default=0.0), 1),
        "wall_s": round(time.perf_counter() - wall0, 2),
        "ask_errors": watch.ask_errors,
        "false_failures": watch.failures[failures:],
        "stats": {k: v - stats0.get(k, 0) for k, v in counted.items() if v != stats0.get(k, 0)},
    }
    ok = done and refused == n and not figures["false_failures"] and not watch.ask_errors
    return attack.name, ok, figures


@contextlib.contextmanager
def _raw_dealer(ctx: zmq.Context[Any], name: str, endpoint: str) -> Iterator[tuple[Any, bytes]]:
    """A local process under a made-up name, saying hello like btcap (an instance token)
    from where it listens, so the target's dials back succeed and it stays a peer; yields
    its socket and its hello, sent again before each attack."""
    listener = ctx.socket(zmq.ROUTER)
    listener.setsockopt(zmq.LINGER, 0)
    listener.bind(_TCP)
    where = listener.getsockopt_string(zmq.LAST_ENDPOINT)
    hello = f"H{where}\n{name}-instance".encode()
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.ROUTING_ID, name.encode())
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.SNDHWM, 0)
    sock.connect(endpoint)
    sock.send(hello)
    try:
        yield sock, hello
    finally:
        sock.close()
        listener.close()


async def _keyed(quick: bool) -> list[Result]:
    with tempfile.TemporaryDirectory(prefix="btcap-decode-") as tmp:
        keys = Path(tmp)
        for name, role in _KEYS.items():
            write_key_pair(keys, name, role)
        async with _team(keys) as (_r1, _origin, watch, t1):
            eye = ZmqTransport("eye", _TCP, registry(), keys=keys / "eye.key_secret", trusted=keys)
            eye.limit(role_table())
            serving = asyncio.create_task(eye.serve(lambda _e: None, task_status=_Started()))
            try:
                eye.add_peer("r1", t1.endpoint)
                shapes = frames(eye.codec, "eye", quick)
                attack = Attack("observer_nested_calls", "eye", shapes["calls"], _ROLE)
                await until(lambda: "eye" in t1.peers(), 5.0)
                return [await _strike(attack, eye._dealers["r1"], t1, watch)]
            finally:
                eye.close()
                await asyncio.gather(serving, return_exceptions=True)


class _Started:
    def started(self, value: object = None) -> None:
        del value


async def _keyless(quick: bool) -> list[Result]:
    results: list[Result] = []
    async with _team(None) as (_r1, origin, watch, t1):
        shapes = frames(t1.codec, "mallory", quick)
        ctx: zmq.Context[Any] = zmq.Context()
        try:
            with _raw_dealer(ctx, "mallory", t1.endpoint) as (sock, hello):
                await until(lambda: "mallory" in t1.peers(), 5.0)
                for attack in (
                    Attack("stranger_nested_calls", "mallory", shapes["calls"], _TOO_BIG, hello),
                    Attack(
                        "stranger_nested_small", "mallory", shapes["calls_small"], _NESTED, hello
                    ),
                ):
                    results.append(await _strike(attack, sock, t1, watch))
        finally:
            ctx.term()
        to = origin.system.transport
        assert isinstance(to, ZmqTransport)
        shapes = frames(to.codec, "origin", quick)
        link = to._dealers["r1"]  # a member's own link: what a member that turned sends
        for attack in (
            Attack("member_nested_calls", "origin", shapes["calls"], _NESTED),
            Attack("member_nested_tasks", "origin", shapes["tasks"], _NESTED),
        ):
            results.append(await _strike(attack, link, t1, watch))
    return results


_ROLE = "not allowed for its role"
_TOO_BIG = "too big for a non-member"
_NESTED = "nested too much"


async def probe_decode(quick: bool) -> list[Result]:
    """One result per attack (see the module's docstring)."""
    return await _keyed(quick) + await _keyless(quick)
