"""What a ZeroMQ transport checks before it decodes a message (issue 29): the sender's
role (from the message's tag), a non-member's size, every message's containers and
depth; and a hello without an instance token, which must not move a known peer.

Loopback tcp on ports the OS picks; raw pyzmq DEALERs as the attackers."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator, Iterator
from typing import Any

import anyio
import msgspec
import zmq

from btcap.actors import ActorSystem, Address
from btcap.transports import Kind, Message, ZmqTransport
from btcap.transports.bounds import MAX_DEPTH
from btcap.transports.identity import OBSERVER
from tests.transports.peer_process import Echo
from tests.transports.test_zeromq import eventually, registry, zmq_system

TCP = "tcp://127.0.0.1:*"
ROLE = "not allowed for its role"
TOO_BIG = "too big for a non-member"
NESTED = "nested too much"
NO_INSTANCE = "hello without an instance token"


class Free(Message):
    """A message with a free-form field, as capability inputs are."""

    value: Any


def nest(depth: int) -> Any:
    value: Any = 0
    for _ in range(depth):
        value = [value]
    return value


@contextlib.asynccontextmanager
async def target(**kwargs: Any) -> AsyncIterator[tuple[ActorSystem, ZmqTransport]]:
    reg = registry()
    reg.register(Free)
    async with zmq_system("a", ZmqTransport("a", TCP, reg, **kwargs)) as pair:
        yield pair


@contextlib.contextmanager
def attacker(name: str, endpoint: str) -> Iterator[zmq.Socket[bytes]]:
    """A raw DEALER that said hello as ``name``, from where it listens (so it stays a peer)."""
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
    listener, sock = ctx.socket(zmq.ROUTER), ctx.socket(zmq.DEALER)
    try:
        listener.setsockopt(zmq.LINGER, 0)
        listener.bind(TCP)
        where = listener.getsockopt_string(zmq.LAST_ENDPOINT)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.ROUTING_ID, name.encode())
        sock.connect(endpoint)
        sock.send(f"H{where}\n{name}-1".encode())
        yield sock
    finally:
        sock.close(0)
        listener.close(0)


def frame(transport: ZmqTransport, sender: str, msg: Message | msgspec.Raw) -> bytes:
    env = (Kind.TELL, Address(sender, "x"), Address(transport.system_id, "inbox"), msg, 0)
    return b"M" + msgspec.msgpack.encode(env)


def counted(transport: ZmqTransport, reason: str) -> int:
    return transport.stats.by_reason.get(reason, 0)


async def test_a_role_is_checked_before_the_message_is_decoded() -> None:
    """An observer's message of a type it may not send is refused by its tag: a body
    that would not even decode is refused for the role, not found malformed."""
    with anyio.fail_after(10):
        async with target() as (_a, ta):
            ta.limit({OBSERVER: frozenset({Free})})
            with attacker("eye+x", ta.endpoint) as eye:
                await eventually(lambda: "eye+x" in ta.peers(), "eye said hello")
                bogus = msgspec.Raw(msgspec.msgpack.encode(["Note", 1, 2, 3]))  # not a Note
                eye.send(frame(ta, "eye+x", bogus))
                await eventually(lambda: counted(ta, ROLE) == 1, "refused for its role")
                eye.send(frame(ta, "eye+x", Free(nest(3))))  # allowed: delivered
                await eventually(lambda: ta.stats.received == 2, "the allowed one delivered")
            assert ta.stats.malformed == 0


async def test_a_non_member_may_send_only_small_messages() -> None:
    with anyio.fail_after(10):
        async with target() as (_a, ta):
            ta.members(lambda peer: peer == "friend")
            big = Free("x" * 300_000)  # plain data: only its size matters
            with (
                attacker("mallory", ta.endpoint) as mallory,
                attacker("friend", ta.endpoint) as friend,
            ):
                await eventually(lambda: {"mallory", "friend"} <= ta.peers(), "both said hello")
                mallory.send(frame(ta, "mallory", big))
                mallory.send(frame(ta, "mallory", Free("small")))
                friend.send(frame(ta, "friend", big))
                await eventually(lambda: ta.stats.received == 2, "small and member's delivered")
                assert counted(ta, TOO_BIG) == 1
                ta.members(None)  # nobody is told apart: the frame limit alone
                mallory.send(frame(ta, "mallory", big))
                await eventually(lambda: ta.stats.received == 3, "delivered without a check")
            assert counted(ta, TOO_BIG) == 1


async def test_every_message_is_held_to_its_containers_and_depth() -> None:
    """Small frames and big ones (read in Python before msgspec walks them): nested
    too much is refused and counted whoever sends it; within bounds it is delivered."""
    with anyio.fail_after(20):
        async with target() as (_a, ta):
            with attacker("r9", ta.endpoint) as r9:
                await eventually(lambda: "r9" in ta.peers(), "r9 said hello")
                sent = [
                    (Free(nest(MAX_DEPTH + 5)), True),
                    (Free([nest(100) for _ in range(30_000)]), True),  # 3 MB: the attack
                    (Free([[] for _ in range(40_000)]), True),  # shallow, too many
                    (Free(nest(MAX_DEPTH - 2)), False),
                    (Free([[i, -i] for i in range(30_000)]), False),  # 30,000 waypoints
                    (Free([0.5] * 400_000), False),  # 3.6 MB of floats
                ]
                for msg, _ in sent:
                    r9.send(frame(ta, "r9", msg))
                refused = sum(bad for _, bad in sent)
                await eventually(
                    lambda: counted(ta, NESTED) + ta.stats.received == len(sent), "all handled"
                )
            assert counted(ta, NESTED) == refused
            assert ta.stats.received == len(sent) - refused


async def test_a_hello_without_an_instance_never_moves_a_known_peer() -> None:
    """Any local process (keyless) says hello under a live peer's name without an
    instance token: the peer's entry keeps its endpoint; counted and logged."""
    with anyio.fail_after(10):
        async with target() as (a, ta), zmq_system("r1", TCP) as (r1, t1):
            t1.add_peer("a", ta.endpoint)
            await eventually(lambda: ta.endpoint_of("r1") == t1.endpoint, "a knows r1")
            ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
            sock = ctx.socket(zmq.DEALER)
            try:
                sock.setsockopt(zmq.LINGER, 0)
                sock.setsockopt(zmq.ROUTING_ID, b"r1/forged")
                sock.connect(ta.endpoint)
                sock.send(b"H" + b"tcp://127.0.0.1:9")
                await eventually(lambda: counted(ta, NO_INSTANCE) == 1, "refused and counted")
            finally:
                sock.close(0)
            assert ta.endpoint_of("r1") == t1.endpoint
            assert await a.ask(Address("r1", "echo"), Echo("still there"), timeout=5.0) is not None
            del r1
