"""Attack probe, silent connections: raw TCP connections that complete the ZMTP handshake
(NULL mechanism: any local process may, against a team without keys) and then never say
a word. Each holds a descriptor of the target while it is open; the target must close
those that say no hello within its deadline, and hold at most its cap meanwhile.

Figures: the descriptors the target held after ``n`` such connections (once they were
open, and once its deadline passed), beside ``n``; an honest peer's asks must all be
answered meanwhile;
the same run opens as many against a target whose limits never bite (what was held
before them). Hooked into
:mod:`btcap.bench.attacks.probe` (``python -m btcap.bench attacks --quick`` runs it).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import socket
import struct
import time
from collections.abc import AsyncIterator, Iterator
from typing import Any

from btcap.actors import Actor, ActorSystem, Address, handler
from btcap.bench.attacks.echo import until
from btcap.bench.attacks.hostile import Ping, Pong, registry
from btcap.transports import ZmqTransport
from btcap.transports.zmq_newcomers import NO_HELLO

__all__ = ["frame", "greet", "hung_up", "probe_silent", "silent_connections"]

_HOST = "127.0.0.1"
_DEADLINE_S = 1.0
_CAP = 32
_SETTLE_S = 30.0
_SLACK = 4  # files the process may open meanwhile for other reasons

Result = tuple[str, bool, dict[str, Any]]


def _greeting() -> bytes:
    """ZMTP 3.0's greeting for the NULL mechanism, as a client."""
    return b"\xff" + bytes(8) + b"\x7f" + b"\x03\x00" + b"NULL".ljust(20, b"\0") + bytes(32)


def _ready(identity: bytes) -> bytes:
    """The READY command of a DEALER (NULL mechanism), as a short command frame."""
    body = b"\x05READY"
    for name, value in ((b"Socket-Type", b"DEALER"), (b"Identity", identity)):
        body += bytes([len(name)]) + name + struct.pack(">I", len(value)) + value
    return bytes([0x04, len(body)]) + body


def frame(body: bytes) -> bytes:
    """One ZMTP message frame (the last of its message) carrying ``body``."""
    if len(body) < 256:
        return bytes([0x00, len(body)]) + body
    return b"\x02" + struct.pack(">Q", len(body)) + body


def greet(port: int, identity: bytes = b"", timeout: float = 10.0) -> socket.socket:
    """A raw connection to a ZeroMQ socket at ``127.0.0.1:port`` that completes the
    NULL handshake (its greeting and READY read back; ``identity``: the routing id it
    asks for) and then says nothing."""
    sock = socket.create_connection((_HOST, port), timeout=timeout)
    try:
        sock.sendall(_greeting() + _ready(identity))
        got = b""
        while len(got) < 64 + 2:  # the server's greeting and the head of its READY
            chunk = sock.recv(4096)
            if not chunk:
                raise ConnectionError("the server closed the connection in its handshake")
            got += chunk
        size = got[65]
        while len(got) < 64 + 2 + size:
            chunk = sock.recv(4096)
            if not chunk:
                raise ConnectionError("the server closed the connection in its handshake")
            got += chunk
    except BaseException:
        sock.close()
        raise
    return sock


def hung_up(sock: socket.socket) -> bool:
    """Whether the other end closed ``sock`` (a read finds its end, not silence)."""
    sock.setblocking(False)
    try:
        return sock.recv(1) == b""
    except BlockingIOError:
        return False
    except OSError:
        return True


@contextlib.contextmanager
def silent_connections(port: int, n: int) -> Iterator[list[socket.socket]]:
    """``n`` raw silent connections (see :func:`greet`), closed when the block ends."""
    socks: list[socket.socket] = []
    try:
        for _ in range(n):
            socks.append(greet(port))
        yield socks
    finally:
        for sock in socks:
            sock.close()


def _port(endpoint: str) -> int:
    return int(endpoint.rsplit(":", 1)[1])


def _open_files() -> int:
    return len(os.listdir("/proc/self/fd"))


class _Echo(Actor):
    @handler
    def ping(self, msg: Ping) -> Pong:
        return Pong(msg.seq)


@contextlib.asynccontextmanager
async def _pair(**target: Any) -> AsyncIterator[tuple[ActorSystem, ZmqTransport]]:
    """The target ``r1`` (answering pings) and an honest peer ``origin`` that knows it."""
    reg_r1, reg_o = registry(), registry()
    t1 = ZmqTransport("r1", f"tcp://{_HOST}:*", reg_r1, **target)
    to = ZmqTransport("origin", f"tcp://{_HOST}:*", reg_o, peers={"r1": t1.endpoint})
    try:
        async with (
            ActorSystem(transport=t1, registry=reg_r1) as r1,
            ActorSystem(transport=to, registry=reg_o, ask_timeout=5.0) as origin,
        ):
            r1.spawn(_Echo(), "echo")
            yield origin, t1
    finally:
        t1.close()
        to.close()


async def _flood(n: int, **target: Any) -> dict[str, Any]:
    """``n`` silent connections to a target made with ``target``'s options while an
    honest peer asks it: what the target held once they were open, and once they
    should have been closed (after its deadline, at most :data:`_SETTLE_S`)."""
    async with _pair(**target) as (origin, t1):
        echo = Address("r1", "echo")
        await origin.ask(echo, Ping(0))  # the honest link is up
        before = _open_files()
        port = _port(t1.endpoint)
        socks: list[socket.socket] = []
        try:
            for _ in range(n):
                socks.append(await asyncio.to_thread(greet, port))

            def held() -> int:  # the process's files, less the attacker's own ends
                return _open_files() - before - len(socks)

            cap = target.get("max_newcomers", n)
            evicted = max(0, n - cap)
            await until(lambda: t1.stats.by_reason.get(NO_HELLO, 0) >= evicted, _SETTLE_S)
            await until(lambda: held() <= cap, _SETTLE_S)  # libzmq closes them in its thread
            held_flood = held()
            errors = 0
            for seq in range(1, 4):
                try:
                    await origin.ask(echo, Ping(seq))
                except Exception:
                    errors += 1
            deadline = target.get("hello_timeout_s", 0.0)
            closed = deadline < _SETTLE_S and await until(
                lambda: all(hung_up(s) for s in socks), _SETTLE_S
            )
            if closed:
                await until(lambda: held() <= 0, _SETTLE_S)
            held_after = held()
        finally:
            for sock in socks:
                sock.close()
        return {
            "held_flood": held_flood,
            "held_after": held_after,
            "closed_all": closed,
            "no_hello": t1.stats.by_reason.get(NO_HELLO, 0),
            "ask_errors": errors,
        }


async def probe_silent(quick: bool) -> list[Result]:
    """``n`` silent connections to a target (deadline 1 s, cap 32), and the same to a
    target whose limits never bite (the peer figure: what held without them)."""
    n = 200 if quick else 1_000
    t0 = time.perf_counter()
    got = await _flood(n, hello_timeout_s=_DEADLINE_S, max_newcomers=_CAP)
    seconds = time.perf_counter() - t0
    unlimited = await _flood(n, hello_timeout_s=3_600.0, max_newcomers=1_000_000)
    figures = {
        "connections": n,
        "cap": _CAP,
        "deadline_s": _DEADLINE_S,
        **got,
        "held_without_limits": unlimited["held_flood"],
        "seconds": round(seconds, 2),
    }
    ok = got["closed_all"] and got["held_flood"] <= _CAP + _SLACK and got["held_after"] <= 0
    ok = ok and got["ask_errors"] == 0
    return [("silent_connections", ok, figures)]
