"""The bidders of :mod:`bench.speed.auction_floor`, in their own OS processes, and what both
sides share: the messages (msgpack arrays padded to btcap's sizes) and the sockets.

``python -m btcap.bench.speed.auction_floor_peers --serve blocking|asyncio --ids 0,4,8
--auctioneer ENDPOINT`` binds a ROUTER per bidder, connects a DEALER per bidder to the
auctioneer, prints ``READY ENDPOINT...`` (in the order of ``--ids``) and answers until
its stdin closes. CURVE keys come in the environment (:data:`KEYS_ENV`), never in argv.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

import msgspec
import zmq

from btcap.bench.speed.transport_peers import until_stdin_closes

__all__ = [
    "ACCEPT",
    "AWARD",
    "BID",
    "CALL",
    "CANCEL",
    "EVENTS",
    "KEYS_ENV",
    "NOBLOCK",
    "POLLIN",
    "READY",
    "SIZES",
    "VARIANTS",
    "Keys",
    "dealer",
    "decode",
    "keys_from_env",
    "make_keys",
    "message",
    "router",
]

VARIANTS = ("blocking", "asyncio")
SIZES = {"call": 160, "bid": 91, "award": 123, "accept": 89, "cancel": 83}
"""Bytes on the wire per message of btcap's round (its frame: kind byte and envelope)."""
CALL, BID, AWARD, ACCEPT, CANCEL = range(5)
NOBLOCK = int(zmq.NOBLOCK)
EVENTS = int(zmq.EVENTS)
POLLIN = int(zmq.POLLIN)
READY = "READY "
_TCP = "tcp://127.0.0.1:*"
KEYS_ENV = "BTCAP_AUCTION_FLOOR_KEYS"
_encode = msgspec.msgpack.encode
decode = msgspec.msgpack.Decoder(tuple[int, int, int, float, str]).decode


def _padding(kind: int, size: int) -> str:
    bare = len(_encode((kind, 1, 1, 1.0, "")))
    return "x" * (size - bare - (1 if size - bare > 31 else 0))  # a str over 31: 1 byte more


_PAD = [_padding(kind, size) for kind, size in enumerate(SIZES.values())]


def message(kind: int, rnd: int, bidder: int = 0, cost: float = 0.0) -> bytes:
    """``[kind, round, bidder, cost, padding]``, padded to btcap's size of that message."""
    return _encode((kind, rnd, bidder, cost, _PAD[kind]))


Keys = tuple[bytes, bytes, bytes, bytes]
"""(server public, server secret, client public, client secret), z85."""


def make_keys() -> Keys:
    return (*zmq.curve_keypair(), *zmq.curve_keypair())


def router(ctx: zmq.Context[zmq.Socket[bytes]], keys: Keys | None) -> zmq.Socket[bytes]:
    sock = ctx.socket(zmq.ROUTER)
    sock.setsockopt(zmq.LINGER, 0)
    if keys is not None:
        sock.setsockopt(zmq.CURVE_SERVER, 1)
        sock.setsockopt(zmq.CURVE_SECRETKEY, keys[1])
    sock.bind(_TCP)
    return sock


def dealer(
    ctx: zmq.Context[zmq.Socket[bytes]], keys: Keys | None, endpoint: str
) -> zmq.Socket[bytes]:
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.LINGER, 0)
    if keys is not None:
        sock.setsockopt(zmq.CURVE_SERVERKEY, keys[0])
        sock.setsockopt(zmq.CURVE_PUBLICKEY, keys[2])
        sock.setsockopt(zmq.CURVE_SECRETKEY, keys[3])
    sock.connect(endpoint)
    return sock


def _answer(body: bytes, index: int) -> bytes | None:
    """A bidder's answer to one message: a bid to a call, an accept to an award."""
    kind, rnd, _, _, _ = decode(body)
    if kind == CALL:
        return message(BID, rnd, index, 1.0 + index)
    if kind == AWARD:
        return message(ACCEPT, rnd, index)
    return None  # a cancel: nothing to say


# -- bidder processes -----------------------------------------------------------------


def _serve(variant: str, indices: Sequence[int], auctioneer: str, keys: Keys | None) -> None:
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    routers = [router(ctx, keys) for _ in indices]
    dealers = [dealer(ctx, keys, auctioneer) for _ in indices]
    ends = " ".join(r.getsockopt_string(zmq.LAST_ENDPOINT) for r in routers)
    print(READY + ends, flush=True)
    try:
        if variant == "blocking":
            _serve_blocking(routers, dealers, indices)
        else:
            asyncio.run(_serve_async(routers, dealers, indices))
    finally:
        for sock in (*routers, *dealers):
            sock.close(0)
        ctx.term()


def _serve_blocking(
    routers: list[zmq.Socket[bytes]], dealers: list[zmq.Socket[bytes]], indices: Sequence[int]
) -> None:
    poller = zmq.Poller()
    by_socket = {}
    for router, dealer, index in zip(routers, dealers, indices, strict=True):
        poller.register(router, zmq.POLLIN)
        by_socket[router] = (dealer, index)
    stdin = sys.stdin.fileno()
    poller.register(stdin, zmq.POLLIN)
    while True:
        for sock, _ in poller.poll():
            if sock == stdin:
                if not os.read(stdin, 4096):
                    return
                continue
            dealer, index = by_socket[sock]
            _ident, body = sock.recv_multipart()
            out = _answer(body, index)
            if out is not None:
                dealer.send(out)


async def _serve_async(
    routers: list[zmq.Socket[bytes]], dealers: list[zmq.Socket[bytes]], indices: Sequence[int]
) -> None:
    loop = asyncio.get_running_loop()
    fds = []
    for router, dealer, index in zip(routers, dealers, indices, strict=True):
        readable = _drain(router, dealer.send, index)
        fd = router.getsockopt(zmq.FD)
        assert isinstance(fd, int)
        loop.add_reader(fd, readable)
        loop.call_soon(readable)  # edge-triggered: what came before we watched
        fds.append(fd)
    try:
        await until_stdin_closes()
    finally:
        for fd in fds:
            loop.remove_reader(fd)


def _drain(router: zmq.Socket[bytes], send: Callable[..., Any], index: int) -> Callable[[], None]:
    get, recv = router.get, router.recv

    def readable() -> None:
        while get(EVENTS) & POLLIN:  # type: ignore[operator]
            recv(NOBLOCK)  # the asker's routing id
            out = _answer(recv(NOBLOCK), index)
            if out is not None:
                send(out, NOBLOCK)

    return readable


def keys_from_env() -> Keys | None:
    text = os.environ.get(KEYS_ENV)
    if not text:
        return None
    p = text.encode().split()
    return p[0], p[1], p[2], p[3]


def main(argv: Sequence[str] | None = None) -> int:
    prog = "python -m btcap.bench.speed.auction_floor_peers"
    parser = argparse.ArgumentParser(prog=prog, description=__doc__)
    parser.add_argument("--serve", choices=VARIANTS, required=True, help="how to wait")
    parser.add_argument("--ids", required=True, help="the bidders' indices, comma-separated")
    parser.add_argument("--auctioneer", required=True, help="the auctioneer's endpoint")
    args = parser.parse_args(argv)
    ids = [int(i) for i in args.ids.split(",") if i]
    _serve(args.serve, ids, args.auctioneer, keys_from_env())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
