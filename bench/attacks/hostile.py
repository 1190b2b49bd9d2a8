"""What the attack probe's attacker sends: raw pyzmq frames, built by hand.

Plain blocking pyzmq, run in a thread so the team's loop goes on. Every sender says hello
first (the target then knows it as a peer) from an address where nobody listens.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import zmq

from btcap.actors import Address, Message
from btcap.team.ids import ExecutionId
from btcap.team.membership.membership import Membership
from btcap.team.messages import ExecutionInputs, Heartbeat, RepositoryState
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import MessageRegistry
from btcap.transports.codec import Codec, Envelope, Kind

__all__ = [
    "ATTACKER",
    "Ping",
    "Pong",
    "dealer",
    "deep",
    "fake_states",
    "hello_flood",
    "junk",
    "oversized",
    "registry",
]

ATTACKER = "mallory"
_DEAD = "tcp://127.0.0.1:9"  # discard port: where forged hellos say they live


class Ping(Message):
    seq: int


class Pong(Message):
    seq: int


class Bogus(Message):
    """A type the team never registered."""

    blob: str


class WrongState(Message, tag="RepositoryState"):
    """The team's ``RepositoryState`` tag with fields of the wrong types."""

    robot: int
    version: str


def registry() -> MessageRegistry:
    reg = protocol_registry()
    reg.register(Ping, Pong)
    return reg


def _frame(codec: Codec, msg: Message, path: str, sender: str = ATTACKER) -> bytes:
    """A message frame as :mod:`~btcap.transports.zeromq` sends it: ``M`` + envelope."""
    env = Envelope(Kind.TELL, Address(sender, "x"), Address("r1", path), msg)
    return b"M" + codec.encode(env)


@contextlib.contextmanager
def dealer(ctx: zmq.Context[Any], ident: str, endpoint: str) -> Iterator[zmq.Socket[Any]]:
    """A raw DEALER that has said hello as ``ident`` (the target then knows it as a peer)."""
    sock = ctx.socket(zmq.DEALER)
    sock.setsockopt(zmq.ROUTING_ID, ident.encode())
    sock.setsockopt(zmq.LINGER, 2000)
    sock.setsockopt(zmq.SNDHWM, 0)
    sock.connect(endpoint)
    sock.send(b"H" + _DEAD.encode())
    try:
        yield sock
    finally:
        sock.close()


def hello_flood(endpoint: str, n: int) -> None:
    for start in range(0, n, 100):
        # A context per batch: its term() really closes them, so the attacker's own open
        # files stay bounded (at most 100 sockets at once).
        ctx: zmq.Context[Any] = zmq.Context()
        try:
            for i in range(start, min(n, start + 100)):
                sock = ctx.socket(zmq.DEALER)
                sock.setsockopt(zmq.ROUTING_ID, f"ghost-{i}".encode())
                sock.setsockopt(zmq.LINGER, 1000)
                sock.connect(endpoint)
                sock.send(b"H" + _DEAD.encode())
                sock.close()
        finally:
            ctx.term()


def fake_states(endpoint: str, n: int, size: int) -> None:
    codec = Codec(registry())
    filler = "i" * 1000
    interfaces = {f"Iface{k}": filler for k in range(size // 1000)}
    ctx: zmq.Context[Any] = zmq.Context()
    try:
        with dealer(ctx, ATTACKER, endpoint) as sock:
            for i in range(n):
                # Half for invented robots, half claiming to be the (non-member) sender.
                robot = f"ghost-{i}" if i % 2 else ATTACKER
                state = RepositoryState(robot, 1, interfaces)
                sock.send(_frame(codec, state, "repository"))
    finally:
        ctx.term()


def junk(endpoint: str, n: int) -> None:
    reg = registry()
    reg.register(Bogus)
    codec = Codec(reg)
    # WrongState shares RepositoryState's tag: a registry of its own encodes it.
    wrong = Codec(MessageRegistry([WrongState]))
    kinds = [
        _frame(codec, Bogus("x" * 200), "repository"),
        _frame(wrong, WrongState(7, "v"), "repository"),
        _frame(codec, Heartbeat("r1", 1, 1), Membership.PATH),  # forged: claims to be r1
        _frame(codec, Ping(1), "nobody"),  # no such actor
        deep(_frame(codec, ExecutionInputs(ExecutionId("x", "n", 1), 1, {"v": "NEST"}), "x")),
    ]
    ctx: zmq.Context[Any] = zmq.Context()
    try:
        with dealer(ctx, ATTACKER, endpoint) as sock:
            for i in range(n):
                sock.send(kinds[i % len(kinds)])
    finally:
        ctx.term()


def deep(frame: bytes) -> bytes:
    """``frame`` with its placeholder input replaced by arrays nested 20,000 deep."""
    return frame.replace(b"\xa4NEST", b"\x91" * 20_000 + b"\xc0")


def oversized(endpoint: str, size: int) -> None:
    ctx: zmq.Context[Any] = zmq.Context()
    try:
        with dealer(ctx, "bigmouth", endpoint) as sock:
            sock.send(b"M" + b"\0" * size)
    finally:
        ctx.term()
