"""Inbound connections that complete the handshake and say no hello are closed: after
``hello_timeout_s``, or at once beyond ``max_newcomers`` (the oldest first); a peer's
link the transport dropped must say hello again; honest links stay.

Real raw connections on loopback tcp (OS-chosen ports): NULL handshakes written by hand
(bench/attacks/silent.py) without keys, a pyzmq DEALER holding a team key with them.
Judged by what each connection sees (its end hung up, or not) and the target's counters.
"""

from __future__ import annotations

import contextlib
import secrets
import shutil
import socket
from collections.abc import Callable, Iterator
from pathlib import Path

import anyio
import pytest
import zmq
import zmq.auth
from structlog.testing import capture_logs

from btcap.actors import Address
from btcap.bench.attacks.silent import frame, greet, hung_up
from btcap.transports import ZmqTransport
from btcap.transports.security import write_key_pair
from btcap.transports.zmq_newcomers import NO_HELLO
from tests.transports.peer_process import Echo, messages
from tests.transports.test_zeromq import zmq_system

TCP = "tcp://127.0.0.1:*"
LIMIT_S = 30


@pytest.fixture(autouse=True)
def quiet_logs() -> Iterator[None]:
    with capture_logs():
        yield


def port(t: ZmqTransport) -> int:
    return int(t.endpoint.rsplit(":", 1)[1])


@contextlib.contextmanager
def raw(
    t: ZmqTransport, n: int, identity: Callable[[int], bytes] = lambda _: b""
) -> Iterator[list[socket.socket]]:
    socks: list[socket.socket] = []
    try:
        for i in range(n):
            socks.append(greet(port(t), identity(i)))
        yield socks
    finally:
        for sock in socks:
            sock.close()


async def until(cond: Callable[[], bool]) -> None:
    while not cond():  # noqa: ASYNC110 - a peer's end hanging up has no event here
        await anyio.sleep(0.005)


def no_hello(t: ZmqTransport) -> int:
    return t.stats.by_reason.get(NO_HELLO, 0)


async def test_silent_connections_are_closed_after_the_deadline() -> None:
    with anyio.fail_after(LIMIT_S):
        async with zmq_system("a", TCP, hello_timeout_s=0.3) as (_, ta):
            with raw(ta, 20) as socks:
                await until(lambda: all(hung_up(s) for s in socks))
            assert no_hello(ta) == 20


async def test_beyond_the_cap_the_oldest_are_closed_at_once() -> None:
    with anyio.fail_after(LIMIT_S):
        async with zmq_system("a", TCP, hello_timeout_s=3600.0, max_newcomers=4) as (_, ta):
            with raw(ta, 10) as socks:
                await until(lambda: no_hello(ta) >= 6)
                await until(lambda: all(hung_up(s) for s in socks[:6]))
                assert not any(hung_up(s) for s in socks[6:])  # within the cap, not yet due
            assert no_hello(ta) == 6


async def test_honest_links_stay_while_a_silent_one_is_closed() -> None:
    """The silent connection opens after the honest link: once it is closed, the honest
    link's deadline has passed too, and it is still up."""
    with anyio.fail_after(LIMIT_S):
        async with (
            zmq_system("a", TCP, hello_timeout_s=0.3) as (a, ta),
            zmq_system("b", TCP, hello_timeout_s=0.3) as (b, tb),
        ):
            ta.add_peer("b", tb.endpoint)
            await a.ask(Address("b", "echo"), Echo("up"))
            await b.ask(Address("a", "echo"), Echo("up"))
            hellos = (ta.hellos, tb.hellos)
            with raw(ta, 1) as socks, raw(tb, 1) as more:
                await until(lambda: hung_up(socks[0]) and hung_up(more[0]))
                # Counted as it is shut (an honest link, older, would be shut first).
                assert (no_hello(ta), no_hello(tb)) == (1, 1)
                # libzmq lets go of a shut connection in its I/O thread, and the loop
                # reads its DISCONNECTED event after that: wait for the event, as a
                # busy machine may take a while.
                await until(lambda: ta.disconnects >= 1 and tb.disconnects >= 1)
            await a.ask(Address("b", "echo"), Echo("still"))
            await b.ask(Address("a", "echo"), Echo("still"))
            assert (ta.disconnects, tb.disconnects) == (1, 1)  # the silent ones only
            assert (ta.hellos, tb.hellos) == hellos  # no honest link was dialled again


async def test_a_made_up_name_dropped_must_say_hello_again() -> None:
    """Hello as a stranger from where nobody listens, then silence: the stranger is
    dropped after its failed dials, and its connection once it has said nothing more."""
    with anyio.fail_after(LIMIT_S):
        async with zmq_system("a", TCP, hello_timeout_s=0.3) as (_, ta):
            ident = lambda i: f"ghost{i}/{secrets.token_hex(4)}".encode()  # noqa: E731
            with raw(ta, 3, ident) as socks:
                for sock in socks:
                    hello = f"Htcp://127.0.0.1:9\n{secrets.token_hex(8)}".encode()
                    sock.sendall(frame(hello))
                await until(lambda: ta.hellos == 3)
                await until(lambda: all(hung_up(s) for s in socks))
                assert not ta.peers()
            assert no_hello(ta) == 3


Ctx = zmq.Context[zmq.Socket[bytes]]


def _silent_dealer(ctx: Ctx, keys: Path, endpoint: str) -> zmq.Socket[bytes]:
    """A DEALER with mallory's team key that completes the CURVE handshake and sends
    nothing (pyzmq reconnects it each time it is closed)."""
    public, secret = zmq.auth.load_certificate(keys / "mallory.key_secret")
    server, _ = zmq.auth.load_certificate(keys / "a.key")
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    sock.curve_publickey, sock.curve_secretkey, sock.curve_serverkey = public, secret, server
    sock.connect(endpoint)
    return sock


async def test_a_key_holder_that_never_speaks_is_closed(tmp_path: Path) -> None:
    team = tmp_path / "team"
    team.mkdir()
    for name in ("a", "mallory"):
        public, _ = write_key_pair(tmp_path, name)
        shutil.copy(public, team / public.name)
    ta = ZmqTransport(
        "a", TCP, messages(), keys=tmp_path / "a.key_secret", trusted=team, hello_timeout_s=0.3
    )
    ctx: Ctx = zmq.Context()
    try:
        with anyio.fail_after(LIMIT_S):
            async with zmq_system("a", ta):
                sock = _silent_dealer(ctx, tmp_path, ta.endpoint)
                try:
                    await until(lambda: no_hello(ta) >= 2)  # closed, and its redial too
                finally:
                    sock.close(0)
            assert ta.stats.unknown_peer == 0  # the handshakes themselves succeeded
    finally:
        ctx.term()


def test_limits_must_be_positive() -> None:
    with pytest.raises(ValueError, match="hello_timeout_s=0"):
        ZmqTransport("a", TCP, messages(), hello_timeout_s=0)
    with pytest.raises(ValueError, match="links_per_peer=1: expected at least 2"):
        ZmqTransport("a", TCP, messages(), links_per_peer=1)


@pytest.mark.parametrize("scheme", ["tcp", "ipc"])
async def test_a_silent_dealer_is_closed_over_tcp_and_ipc(scheme: str, tmp_path: Path) -> None:
    """A pyzmq DEALER that never sends: closed, and its reconnection closed again."""
    bind = TCP if scheme == "tcp" else f"ipc://{tmp_path}/a.sock"
    ctx: Ctx = zmq.Context()
    try:
        with anyio.fail_after(LIMIT_S):
            async with zmq_system("a", bind, hello_timeout_s=0.3) as (_, ta):
                sock = ctx.socket(zmq.DEALER)
                sock.setsockopt(zmq.LINGER, 0)
                sock.connect(ta.endpoint)
                try:
                    await until(lambda: no_hello(ta) >= 2)
                finally:
                    sock.close(0)
    finally:
        ctx.term()
