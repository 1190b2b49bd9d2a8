"""What peers can make a keyless ZeroMQ transport hold (issue 19, item 5): a routing id
already linked is never handed over, peers declared gone are forgotten (no re-dialling,
their descriptors closed), departed one-message peers and hearsay do not pile up.

Loopback tcp on ports the OS picks; descriptors counted in /proc/self/fd."""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from typing import Any

import anyio
import zmq

from btcap.actors import Address
from btcap.transports import Envelope, Kind, ZmqTransport
from tests.transports.peer_process import Echo, Echoed
from tests.transports.test_zeromq import (
    Note,
    eventually,
    inbox,
    note_arrives,
    registry,
    zmq_system,
)

TCP = "tcp://127.0.0.1:*"


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


@contextlib.contextmanager
def raw_dealer(ident: bytes, endpoint: str) -> Iterator[zmq.Socket[bytes]]:
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
    sock = ctx.socket(zmq.DEALER)
    try:
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.ROUTING_ID, ident)
        sock.connect(endpoint)
        yield sock
    finally:
        sock.close(0)


def note_frame(transport: ZmqTransport, sender: str, to: str, text: str) -> bytes:
    env = Envelope(Kind.TELL, Address(sender, "x"), Address(to, "inbox"), Note(text))
    return b"M" + transport.codec.encode(env)


async def test_a_routing_id_already_linked_is_never_handed_over_without_keys() -> None:
    """mallory connects as r1 (its bare name, and r1's very routing id): r1's own link
    stays up and r1's messages keep arriving."""
    with anyio.fail_after(10):
        async with zmq_system("a", TCP) as (a, ta), zmq_system("r1", TCP) as (r1, t1):
            t1.add_peer("a", ta.endpoint)
            await eventually(lambda: "r1" in ta.peers(), "a learnt r1")
            r1.tell(Address("a", "inbox"), Note("before"))
            await note_arrives(a, "before")
            r1_id = t1.routing_id("a")
            assert r1_id.startswith(b"r1/")  # a routing id of its own per connection
            for ident in (b"r1", r1_id):
                with raw_dealer(ident, ta.endpoint) as mallory:
                    mallory.send(b"H" + t1.endpoint.encode())
                    mallory.send(note_frame(ta, "r1", "a", f"mallory as {ident!r}"))
                    await anyio.sleep(0.1)
                    for i in range(3):
                        r1.tell(Address("a", "inbox"), Note(f"real {ident!r} {i}"))
                    await note_arrives(a, f"real {ident!r} 2")
            assert await r1.ref(Address("a", "echo")).ask(Echo("x")) == Echoed("x", "a")
            assert all(f"real {i!r} 2" in inbox(a).notes for i in (b"r1", r1_id))


async def test_a_peer_declared_gone_is_forgotten_and_dialled_back_if_it_speaks() -> None:
    with anyio.fail_after(10):
        async with zmq_system("a", TCP) as (a, ta):
            base = open_fds()
            async with zmq_system("b", TCP, peers={"a": ta.endpoint}) as (b, _tb):
                await eventually(lambda: "b" in ta.peers(), "a learnt b from its hello")
                with_b = open_fds()
                ta.forget("b")
                assert "b" not in ta.peers()
                # Its DEALER and monitor are closed: fewer descriptors, nothing re-dialled.
                await eventually(lambda: open_fds() < with_b, "b's sockets closed")
                a.tell(Address("b", "inbox"), Note("lost"))
                assert ta.stats.by_reason.get("no peer b") == 1
                # A false failure: b speaks again, and a dials it back.
                b.tell(Address("a", "inbox"), Note("still here"))
                await note_arrives(a, "still here")
                assert "b" in ta.peers()
                assert await a.ref(Address("b", "echo")).ask(Echo("back")) == Echoed("back", "b")
                ta.forget("b")
            await eventually(lambda: open_fds() <= base, "back to the baseline", limit=5)


async def test_a_configured_peer_declared_gone_is_dialled_afresh() -> None:
    with anyio.fail_after(10):
        async with (
            zmq_system("b", TCP) as (_b, tb),
            zmq_system("a", TCP, peers={"b": tb.endpoint}) as (a, ta),
        ):
            before = ta.routing_id("b")
            ta.forget("b")  # what was queued goes; the seed stays dialled
            assert "b" in ta.peers()
            assert ta.routing_id("b") != before
            assert await a.ref(Address("b", "echo")).ask(Echo("x")) == Echoed("x", "b")


async def test_departed_one_message_peers_do_not_keep_descriptors() -> None:
    """20 short-lived systems each say hello and one thing, then exit (as ``btcap team
    status`` did): their links drop, they are strangers again and are forgotten."""
    with anyio.fail_after(20):
        async with zmq_system("a", TCP, stranger_ttl_s=0.2) as (a, ta):
            base = open_fds()
            box = inbox(a)
            dropped = ta.stats.by_reason
            for n in range(20):
                async with zmq_system(f"visitor-{n}", TCP, peers={"a": ta.endpoint}) as (v, _):
                    v.tell(Address("a", "inbox"), Note(f"hi {n}"))
                    # A stranger that has not spoken is dropped 0.2 s of wall after its
                    # hello: a machine that stalls a's loop that long drops its note as
                    # from an unknown peer (seen once under load). Either way it is one
                    # more peer to forget.
                    await eventually(
                        lambda n=n: (
                            f"hi {n}" in box.notes
                            or dropped.get("unknown peer", 0) + len(box.notes) > n
                        ),
                        f"visitor-{n}'s note delivered or dropped",
                    )
            assert len(box.notes) + dropped.get("unknown peer", 0) == 20
            await eventually(lambda: not ta.peers(), "every visitor forgotten", limit=10)
            await eventually(lambda: open_fds() <= base + 2, "descriptors released", limit=5)


async def test_hearsay_is_not_dialled_in_bulk() -> None:
    with anyio.fail_after(10):
        async with zmq_system("a", TCP, max_strangers=8) as (_a, ta):
            base = open_fds()
            introduced = [ta.introduce(f"ghost-{n}", f"tcp://127.0.0.1:{9}") for n in range(200)]
            assert sum(introduced) == 8
            assert len(ta.peers()) == 8
            assert ta.stats.by_reason["too many strangers"] == 192
            # Each dialled stranger holds about three descriptors (24 measured here);
            # the slack is for descriptors other parts of the process open or close
            # meanwhile. Dialling all 200 would hold about 600.
            assert open_fds() - base <= 8 * 3 + 16


async def test_a_hello_flood_keeps_at_most_max_strangers() -> None:
    with anyio.fail_after(10):
        async with zmq_system("a", TCP, max_strangers=4) as (_a, ta):
            socks: list[Any] = []
            with contextlib.ExitStack() as stack:
                for n in range(30):
                    sock = stack.enter_context(raw_dealer(f"joiner-{n}".encode(), ta.endpoint))
                    sock.send(f"Hinproc://nowhere-{uuid.uuid4().hex}".encode())
                    socks.append(sock)
                await eventually(lambda: ta.hellos == 30, "every hello handled")
            assert len(ta.peers()) == 4


def test_frames_a_peer_cannot_take_are_counted_never_raised() -> None:
    """Sends never block: to a peer nobody answers, frames queue up to the send limit and
    the rest are counted undeliverable (backed up); a frame over ``max_message_bytes`` is
    not sent at all. The counts add up to what was sent."""
    probe: zmq.Socket[bytes] = zmq.Context.instance().socket(zmq.ROUTER)
    port = probe.bind_to_random_port("tcp://127.0.0.1")
    probe.close(0)  # a port nobody listens on now
    transport = ZmqTransport(
        "a", TCP, registry(), peers={"b": f"tcp://127.0.0.1:{port}"}, max_message_bytes=2048
    )
    try:
        stats = transport.stats
        sent_before = stats.sent  # the hello
        count = 10_100  # over the DEALER's send limit of 10,000
        for i in range(count):
            transport.send(
                Envelope(Kind.TELL, Address("a", "x"), Address("b", "inbox"), Note(str(i)))
            )
        transport.send(Envelope(Kind.TELL, Address("a", "x"), Address("b", "y"), Note("n" * 4000)))
        assert stats.sent - sent_before + stats.undeliverable == count + 1
        assert stats.by_reason["peer b backed up"] >= 100
        assert stats.by_reason["too large to send"] == 1
    finally:
        transport.close()
