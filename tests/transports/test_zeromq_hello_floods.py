"""Hellos any local process can send without keys, in floods: made-up names with instance
tokens (as every btcap peer sends them), and a live peer's name claimed from endless
endpoints. What the target holds for them stays bounded: no instance of a name it did
not keep, a few sockets telling second processes why, a falling rate of log lines.

Loopback tcp on ports the OS picks; raw pyzmq DEALERs as the attackers."""

from __future__ import annotations

import contextlib
import secrets
from collections.abc import Callable, Iterator

import anyio
import pytest
import zmq

from btcap.actors import Address
from btcap.transports import zmq_rules
from btcap.transports.zmq_claims import MAX_TELLING
from tests.transports.peer_process import Echo
from tests.transports.test_zeromq import eventually, zmq_system

TCP = "tcp://127.0.0.1:*"
FLOOD = 120
NAME_TAKEN = "name taken"


@contextlib.contextmanager
def hellos(
    endpoint: str, n: int, name: Callable[[int], str], where: Callable[[int], str]
) -> Iterator[None]:
    """``n`` DEALERs, each saying hello as ``name(i)`` from ``where(i)`` with an instance
    token of its own; open until the block ends."""
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
    socks = []
    try:
        for i in range(n):
            sock = ctx.socket(zmq.DEALER)
            socks.append(sock)
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.ROUTING_ID, name(i).encode())
            sock.connect(endpoint)
            sock.send(f"H{where(i)}\n{secrets.token_hex(8)}".encode())
        yield
    finally:
        for sock in socks:
            sock.close(0)


async def test_made_up_names_leave_no_instance_behind() -> None:
    """Strangers that are dropped (they said hello from where nobody listens, or made
    room for newer ones) take their instance token with them."""
    with anyio.fail_after(30):
        async with zmq_system("a", TCP, max_strangers=8, stranger_ttl_s=0.2) as (_, ta):
            dead = "tcp://127.0.0.1:9"
            with hellos(ta.endpoint, FLOOD, lambda i: f"ghost-{i}", lambda _: dead):
                await eventually(lambda: ta.hellos >= FLOOD, "every hello taken", 20.0)
            await eventually(lambda: len(ta.peers()) <= 8, "the strangers dropped", 10.0)
            assert len(ta._claims.instances) <= len(ta.peers())


async def test_a_live_name_claimed_from_many_endpoints_costs_few_sockets(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Each hello under r1's name from another endpoint is refused as a second process;
    at most :data:`MAX_TELLING` sockets tell them why at once, and r1 is still served."""
    monkeypatch.setattr(zmq_rules, "TELL_S", 60.0)  # every teller would stay open meanwhile
    with anyio.fail_after(30):
        async with zmq_system("a", TCP) as (a, ta), zmq_system("r1", TCP) as (_, t1):
            t1.add_peer("a", ta.endpoint)
            await eventually(lambda: ta.endpoint_of("r1") == t1.endpoint, "a knows r1")
            await a.ask(Address("r1", "echo"), Echo("up"), timeout=5.0)  # the link is up
            where = lambda i: f"tcp://127.0.0.1:{20_000 + i}"  # noqa: E731 - nobody listens
            with hellos(ta.endpoint, FLOOD, lambda i: f"r1/x{i}", where):
                refused = lambda: ta.stats.by_reason.get(NAME_TAKEN, 0)  # noqa: E731
                await eventually(lambda: refused() >= FLOOD, "every claim refused", 20.0)
            assert len(ta._claims._tellers) <= MAX_TELLING
            assert ta._claims.newcomers == FLOOD  # logged at a falling rate (worth_logging)
            assert ta.endpoint_of("r1") == t1.endpoint
            assert await a.ask(Address("r1", "echo"), Echo("still there"), timeout=5.0)
