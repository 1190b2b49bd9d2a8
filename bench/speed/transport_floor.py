"""The floor for an ask on an event loop: hand-written ZeroMQ echo with no btcap at all.

What an asyncio ask over tcp cannot beat, measured next to btcap's in the same run, so
the gap to blocking pyzmq splits into what the event loop costs and what btcap adds.
Both sides run an event loop (asyncio or uvloop) and read ZeroMQ the cheapest way there
is: ``loop.add_reader`` on the socket's descriptor, a ``zmq.EVENTS`` check, ``NOBLOCK``
recv and send, one Future per ask (what one ``await`` needs) and nothing else: no
codec, no timers, no routing.

Two shapes:

- ``floor_tcp``: one connection, a DEALER here and a ROUTER echo there (what pyzmq's
  asyncio echo, ``raw_zmq_tcp``, does with a Future per call);
- ``floor_tcp_pair``: btcap's own shape, a ROUTER bound on each side and a DEALER to the
  other side's ROUTER, so a request and its reply travel on two connections.

With keys, both shapes run CURVE (``*_curve``), and ``raw_zmq_tcp_blocking_curve`` is
blocking pyzmq over CURVE: the floor a CURVE ask compares with.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from collections.abc import AsyncIterator, Callable
from typing import Any

import msgspec
import zmq

from btcap.bench.speed.transport_peers import READY, Ping, child, peer_keys, until_stdin_closes
from btcap.transports import KeyPair
from btcap.transports.zmq_io import fd_of

__all__ = ["floor_tcp", "raw_zmq_tcp_blocking", "serve_blocking", "serve_floor"]

NOBLOCK = int(zmq.NOBLOCK)
EVENTS = int(zmq.EVENTS)
POLLIN = int(zmq.POLLIN)
_TCP = "tcp://127.0.0.1:*"
PAYLOAD = msgspec.msgpack.encode(Ping(0, "x" * 32))

Ask = Callable[[int], Any]
Scenario = tuple[Ask, list[int]]


def _server_keys(sock: zmq.Socket[bytes], keys: str | None) -> None:
    if keys is not None:
        sock.setsockopt(zmq.CURVE_SERVER, 1)
        sock.setsockopt(zmq.CURVE_SECRETKEY, peer_keys(keys).secret)


def _client_keys(sock: zmq.Socket[bytes], keys: str | None, name: str = "main-curve") -> None:
    if keys is not None:
        mine, server = KeyPair.load(f"{keys}/{name}.key_secret"), peer_keys(keys)
        sock.setsockopt(zmq.CURVE_SERVERKEY, server.public)
        sock.setsockopt(zmq.CURVE_PUBLICKEY, mine.public)
        sock.setsockopt(zmq.CURVE_SECRETKEY, mine.secret)


def _drain(
    sock: zmq.Socket[bytes], handle: Callable[[zmq.Socket[bytes]], None]
) -> Callable[[], None]:
    """A reader callback: handle every queued message (zmq's descriptor is edge-triggered)."""
    get = sock.getsockopt

    def readable() -> None:
        while get(EVENTS) & POLLIN:  # type: ignore[operator]
            handle(sock)

    return readable


# -- peers (the other process) --------------------------------------------------------


async def serve_floor(bind: str, keys: str | None, reply_to: str | None) -> None:
    """Echo on a ROUTER from a reader callback: back on the same connection, or (with
    ``reply_to``, btcap's shape) through a DEALER to the asker's ROUTER."""
    loop = asyncio.get_running_loop()
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    router = ctx.socket(zmq.ROUTER)
    router.setsockopt(zmq.LINGER, 0)
    _server_keys(router, keys)
    router.bind(bind)
    dealer = None
    if reply_to is None:

        def echo(sock: zmq.Socket[bytes]) -> None:
            ident = sock.recv(NOBLOCK)
            body = sock.recv(NOBLOCK)
            sock.send(ident, NOBLOCK | zmq.SNDMORE)
            sock.send(body, NOBLOCK)
    else:
        dealer = ctx.socket(zmq.DEALER)
        dealer.setsockopt(zmq.LINGER, 0)
        _client_keys(dealer, keys, "peer")
        dealer.connect(reply_to)
        send = dealer.send

        def echo(sock: zmq.Socket[bytes]) -> None:
            sock.recv(NOBLOCK)
            send(sock.recv(NOBLOCK), NOBLOCK)

    readable = _drain(router, echo)
    fd = fd_of(router)
    loop.add_reader(fd, readable)
    loop.call_soon(readable)
    print(READY + router.getsockopt_string(zmq.LAST_ENDPOINT), flush=True)
    try:
        await until_stdin_closes()
    finally:
        loop.remove_reader(fd)
        for sock in (router, dealer):
            if sock is not None:
                sock.close(0)
        ctx.term()


def serve_blocking(bind: str, keys: str | None) -> None:
    """Blocking pyzmq ROUTER echo: no event loop at all (CURVE with ``keys``)."""
    import os

    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    sock = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    _server_keys(sock, keys)
    sock.bind(bind)
    print(READY + sock.getsockopt_string(zmq.LAST_ENDPOINT), flush=True)
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


# -- askers (this process) ------------------------------------------------------------


class _Waiter:
    """The one Future an ask awaits, set by the reader callback."""

    __slots__ = ("fut",)

    def __init__(self) -> None:
        self.fut: asyncio.Future[bytes] | None = None

    def handle(self, sock: zmq.Socket[bytes]) -> None:
        data = sock.recv(NOBLOCK)
        fut, self.fut = self.fut, None
        if fut is not None and not fut.done():
            fut.set_result(data)


@contextlib.asynccontextmanager
async def floor_tcp(
    loop_name: str, keys: str | None = None, pair: bool = False
) -> AsyncIterator[Scenario]:
    """The cheapest asyncio ask: see the module's docstring (``pair``: btcap's shape)."""
    loop = asyncio.get_running_loop()
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    dealer = ctx.socket(zmq.DEALER)
    dealer.setsockopt(zmq.LINGER, 0)
    _client_keys(dealer, keys)
    inbox = dealer
    args = ["--floor-peer", _TCP, "--loop", loop_name, *(("--keys", keys) if keys else ())]
    if pair:
        inbox = ctx.socket(zmq.ROUTER)
        inbox.setsockopt(zmq.LINGER, 0)
        _server_keys(inbox, keys)
        inbox.bind(_TCP)
        args += ["--reply-to", inbox.getsockopt_string(zmq.LAST_ENDPOINT)]
    waiter = _Waiter()
    if pair:
        handle = waiter.handle

        def on_reply(sock: zmq.Socket[bytes]) -> None:
            sock.recv(NOBLOCK)  # the replying DEALER's routing id
            handle(sock)

        readable = _drain(inbox, on_reply)
    else:
        readable = _drain(inbox, waiter.handle)
    fd = fd_of(inbox)
    try:
        with child(*args) as (endpoint, pid):
            dealer.connect(endpoint)
            loop.add_reader(fd, readable)
            send, get, recv, new = dealer.send, inbox.getsockopt, inbox.recv, loop.create_future

            async def ask(i: int) -> Any:
                send(PAYLOAD, NOBLOCK)
                if get(EVENTS) & POLLIN:  # type: ignore[operator]
                    if pair:
                        recv(NOBLOCK)
                    return recv(NOBLOCK)
                waiter.fut = fut = new()
                return await fut

            try:
                yield ask, [pid]
            finally:
                loop.remove_reader(fd)
    finally:
        dealer.close(0)
        if inbox is not dealer:
            inbox.close(0)
        ctx.term()


@contextlib.asynccontextmanager
async def raw_zmq_tcp_blocking(keys: str | None = None) -> AsyncIterator[Scenario]:
    """The floor with no event loop: blocking pyzmq on both sides (CURVE with ``keys``)."""
    args = ("--raw-peer-blocking", _TCP, *(("--keys", keys) if keys else ()))
    with child(*args) as (endpoint, pid):
        ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
        sock = ctx.socket(zmq.DEALER)
        sock.setsockopt(zmq.LINGER, 0)
        _client_keys(sock, keys)
        sock.connect(endpoint)
        try:

            async def ask(i: int) -> Any:
                sock.send(PAYLOAD)
                return sock.recv()

            yield ask, [pid]
        finally:
            sock.close(0)
            ctx.term()
