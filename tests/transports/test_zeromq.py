"""ZeroMQ transport: systems in one process and in two, hellos, reconnects and junk input.

Loopback only: tcp ports are chosen by the OS, ipc sockets live under ``tmp_path``, and
every socket, system and child process is closed in a ``finally``.
"""

from __future__ import annotations

import asyncio
import contextlib
import random
import subprocess
import sys
import uuid
from collections.abc import AsyncIterator, Callable, Iterator, MutableMapping
from pathlib import Path
from typing import Any

import anyio
import msgspec
import pytest
import zmq
import zmq.asyncio
from anyio.abc import Process
from anyio.streams.buffered import BufferedByteReceiveStream
from structlog.testing import capture_logs

from btcap.actors import Actor, ActorSystem, Address, DeadLetter, Message, handler
from btcap.transports import BROADCAST, Envelope, Kind, MessageRegistry, ZmqTransport
from tests.transports.peer_process import READY, Echo, EchoActor, Echoed, Relay, messages

PEER_SCRIPT = Path(__file__).with_name("peer_process.py")


@pytest.fixture(autouse=True)
def plain_logs() -> Iterator[list[MutableMapping[str, Any]]]:
    """Capture log events (the fuzz test floods them) and show them only on failure."""
    with capture_logs() as entries:
        yield entries
    for entry in entries[-50:]:
        print(entry)


# -- helpers ------------------------------------------------------------------------------


class Note(Message):
    text: str


class Unregistered(Message):
    """Never registered on the receiver: must be rejected as undecodable."""

    n: int


class Inbox(Actor):
    """Collects tells; ``arrived`` is set whenever something comes in."""

    def __init__(self) -> None:
        super().__init__()
        self.notes: list[str] = []
        self.arrived = anyio.Event()

    @handler
    def note(self, msg: Note) -> None:
        self.notes.append(msg.text)
        self.arrived.set()


def registry() -> MessageRegistry:
    reg = messages()
    reg.register(Note)
    return reg


@contextlib.asynccontextmanager
async def zmq_system(
    system_id: str, bind: str | ZmqTransport, **kwargs: Any
) -> AsyncIterator[tuple[ActorSystem, ZmqTransport]]:
    """An actor system on a ZmqTransport with an echo actor and an inbox."""
    if isinstance(bind, ZmqTransport):
        transport, reg = bind, bind.codec.registry
    else:
        reg = registry()
        transport = ZmqTransport(system_id, bind, reg, **kwargs)
    try:
        async with ActorSystem(transport=transport, registry=reg, ask_timeout=5.0) as system:
            system.spawn(EchoActor(), "echo")
            system.spawn(Inbox(), "inbox")
            yield system, transport
    finally:
        transport.close()


def inbox(system: ActorSystem) -> Inbox:
    actor = system.lookup("inbox")
    assert isinstance(actor, Inbox)
    return actor


async def eventually(predicate: Callable[[], bool], what: str, limit: float = 5.0) -> None:
    """Poll until ``predicate()`` holds (hellos and drops arrive asynchronously)."""
    with anyio.fail_after(limit):
        while not predicate():  # noqa: ASYNC110 - counters have no event to wait on
            await anyio.sleep(0.005)
    assert predicate(), what


async def note_arrives(system: ActorSystem, text: str) -> None:
    box = inbox(system)
    with anyio.fail_after(5):
        while text not in box.notes:
            box.arrived = anyio.Event()
            await box.arrived.wait()


def endpoints(scheme: str, tmp_path: Path) -> tuple[str, str, str]:
    if scheme == "inproc":
        tag = uuid.uuid4().hex[:8]
        return (f"inproc://{tag}-a", f"inproc://{tag}-b", f"inproc://{tag}-c")
    if scheme == "ipc":
        return (f"ipc://{tmp_path}/a.sock", f"ipc://{tmp_path}/b.sock", f"ipc://{tmp_path}/c.sock")
    return ("tcp://127.0.0.1:*",) * 3


# -- two systems in one process -----------------------------------------------------------


@pytest.mark.parametrize("scheme", ["inproc", "tcp", "ipc"])
async def test_two_systems_ask_and_tell_both_ways(scheme: str, tmp_path: Path) -> None:
    ep_a, ep_b, _ = endpoints(scheme, tmp_path)
    with anyio.fail_after(10):
        async with (
            zmq_system("a", ep_a) as (a, ta),
            zmq_system("b", ep_b, peers={"a": ta.endpoint}) as (b, tb),
        ):
            # b was told about a; a learns b from b's hello.
            reply = await b.ref(Address("a", "echo")).ask(Echo("hi a"), expect=Echoed)
            assert reply == Echoed("hi a", "a")
            await eventually(lambda: "b" in ta.peers(), "a learnt b from its hello")
            assert ta.peer_endpoints() == {"b": tb.endpoint}
            reply = await a.ref(Address("b", "echo")).ask(Echo("hi b"), expect=Echoed)
            assert reply == Echoed("hi b", "b")

            a.ref(Address("b", "inbox")).tell(Note("from a"))
            b.ref(Address("a", "inbox")).tell(Note("from b"))
            await note_arrives(b, "from a")
            await note_arrives(a, "from b")

            # An ask that crosses the wire twice: a -> b -> a -> b -> a.
            relayed = await a.ref(Address("b", "echo")).ask(Relay(Address("a", "echo"), "loop"))
            assert relayed == Echoed("loop", "a")

            # A missing actor on the far side is a DeadLetter here, not a timeout.
            with pytest.raises(DeadLetter):
                await a.ref(Address("b", "nobody")).ask(Echo("?"))
            assert ta.stats.sent > 0
            assert ta.stats.received > 0
            assert ta.stats.malformed == tb.stats.malformed == 0


@pytest.mark.parametrize("scheme", ["inproc", "tcp"])
async def test_late_joiner_is_answered_and_broadcast_reaches_every_peer(
    scheme: str, tmp_path: Path
) -> None:
    ep_a, ep_b, ep_c = endpoints(scheme, tmp_path)
    with anyio.fail_after(10):
        async with (
            zmq_system("a", ep_a) as (a, ta),
            zmq_system("b", ep_b, peers={"a": ta.endpoint}) as (b, _),
        ):
            await eventually(lambda: ta.peers() == {"b"}, "a learnt b")
            # c joins later, knowing only a; its first ask is answered over the hello.
            async with zmq_system("c", ep_c, peers={"a": ta.endpoint}) as (c, tc):
                reply = await c.ref(Address("a", "echo")).ask(Echo("new here"), expect=Echoed)
                assert reply.by == "a"
                assert ta.peers() == {"b", "c"}
                assert tc.peers() == {"a"}

                a.broadcast("inbox", Note("all hands"))
                await note_arrives(b, "all hands")
                await note_arrives(c, "all hands")
                assert "all hands" not in inbox(a).notes  # include_self defaults to False
                a.broadcast("inbox", Note("me too"), include_self=True)
                await note_arrives(a, "me too")
                await note_arrives(c, "me too")


async def test_peer_restarting_on_the_same_endpoint_learns_us_again() -> None:
    """b only knows a from a's hello; after b restarts, a's reconnect says hello again."""
    with anyio.fail_after(10):
        async with zmq_system("a", "tcp://127.0.0.1:*") as (a, ta):
            async with zmq_system("b", "tcp://127.0.0.1:*") as (_b, tb):
                endpoint = tb.endpoint
                ta.add_peer("b", endpoint)
                await eventually(lambda: "a" in tb.peers(), "b learnt a")
                assert await a.ref(Address("b", "echo")).ask(Echo("1")) == Echoed("1", "b")
            # b is gone: its port may take a moment to be free again.
            transport = None
            with anyio.fail_after(5):
                while transport is None:
                    try:
                        transport = ZmqTransport("b", endpoint, registry())
                    except ValueError:
                        await anyio.sleep(0.05)
            async with zmq_system("b", transport) as (b2, tb2):
                await eventually(lambda: "a" in tb2.peers(), "the new b learnt a", limit=5)
                assert await b2.ref(Address("a", "echo")).ask(Echo("2")) == Echoed("2", "a")
                assert await a.ref(Address("b", "echo")).ask(Echo("3")) == Echoed("3", "b")


async def test_what_we_send_while_a_peer_restarts_reaches_its_new_life(
    plain_logs: list[MutableMapping[str, Any]],
) -> None:
    """Tells to b while it is down wait in a's queue; b's new life hears a's hello before
    them, so it drops none as coming from an unknown peer."""
    with anyio.fail_after(10):
        async with zmq_system("a", "tcp://127.0.0.1:*") as (a, ta):
            async with zmq_system("b", "tcp://127.0.0.1:*") as (_b, tb):
                endpoint = tb.endpoint
                ta.add_peer("b", endpoint)
                await eventually(lambda: "a" in tb.peers(), "b learnt a")
                assert await a.ref(Address("b", "echo")).ask(Echo("1")) == Echoed("1", "b")
            await eventually(
                lambda: any(e["event"] == "transport.peer_relinked" for e in plain_logs),
                "a saw its link to b drop",
            )
            for i in range(5):
                a.tell(Address("b", "inbox"), Note(f"queued {i}"))
            transport = None
            with anyio.fail_after(5):
                while transport is None:
                    try:
                        transport = ZmqTransport("b", endpoint, registry())
                    except ValueError:
                        await anyio.sleep(0.05)
            async with zmq_system("b", transport) as (b2, tb2):
                await note_arrives(b2, "queued 4")
                assert inbox(b2).notes == [f"queued {i}" for i in range(5)]
                assert tb2.stats.unknown_peer == 0


async def test_peer_moving_to_a_new_endpoint_is_followed() -> None:
    with anyio.fail_after(10), capture_logs() as logs:
        async with zmq_system("a", "tcp://127.0.0.1:*") as (a, ta):
            async with zmq_system("b", "tcp://127.0.0.1:*", peers={"a": ta.endpoint}) as (_, tb):
                await eventually(lambda: "b" in ta.peers(), "a learnt b")
                first = tb.endpoint
            # A real move takes longer than a's seeing the old link drop; a hello racing
            # that drop is, as far as a can tell, a second live b (refused: see test_roles).
            await eventually(
                lambda: any(e["event"] == "transport.peer_relinked" for e in logs), "a saw it"
            )
            async with zmq_system("b", "tcp://127.0.0.1:*", peers={"a": ta.endpoint}) as (_, tb):
                assert tb.endpoint != first
                await eventually(lambda: ta.peer_endpoints()["b"] == tb.endpoint, "a followed b")
                assert await a.ref(Address("b", "echo")).ask(Echo("moved")) == Echoed("moved", "b")


async def test_advertised_endpoint_is_what_peers_connect_to(tmp_path: Path) -> None:
    (tmp_path / "alias.sock").symlink_to(tmp_path / "real.sock")
    alias = f"ipc://{tmp_path}/alias.sock"
    with anyio.fail_after(5):
        async with (
            zmq_system("a", f"ipc://{tmp_path}/a.sock") as (a, ta),
            zmq_system(
                "b", f"ipc://{tmp_path}/real.sock", advertise=alias, peers={"a": ta.endpoint}
            ) as (_, tb),
        ):
            assert tb.endpoint == alias
            assert tb.bound_endpoint == f"ipc://{tmp_path}/real.sock"
            await eventually(lambda: "b" in ta.peers(), "a learnt b")
            assert ta.peer_endpoints()["b"] == alias
            assert await a.ref(Address("b", "echo")).ask(Echo("via alias")) == Echoed(
                "via alias", "b"
            )
    with pytest.raises(ValueError, match="advertise"):
        ZmqTransport("c", "tcp://127.0.0.1:*", registry(), advertise="localhost:1")


async def test_hello_refused_when_not_accepting(plain_logs: list[MutableMapping[str, Any]]) -> None:
    with anyio.fail_after(5):
        async with (
            zmq_system("a", "tcp://127.0.0.1:*", accept_hello=False) as (_a, ta),
            zmq_system("b", "tcp://127.0.0.1:*", peers={"a": ta.endpoint}) as (b, _),
        ):
            b.ref(Address("a", "inbox")).tell(Note("let me in"))
            await eventually(lambda: ta.stats.unknown_peer >= 2, "hello and tell refused")
            assert ta.peers() == frozenset()
            assert ta.stats.by_reason["unknown peer"] == ta.stats.unknown_peer
            assert ta.stats.received == 0
            assert any(e["event"] == "transport.dropped" for e in plain_logs)


async def test_the_peer_table_stays_bounded_and_silent_strangers_make_room() -> None:
    """Peers known only from their hello go first when the table is full (a flood of
    made-up ids neither exhausts sockets nor keeps a real newcomer out)."""
    ctx = zmq.asyncio.Context.instance()
    raw: list[zmq.Socket[bytes]] = []
    with anyio.fail_after(5):
        async with zmq_system("a", "tcp://127.0.0.1:*", max_peers=2) as (_a, ta):
            try:
                for n in range(4):
                    sock: zmq.Socket[bytes] = zmq.Socket(ctx, zmq.DEALER)
                    raw.append(sock)
                    sock.setsockopt(zmq.LINGER, 0)
                    sock.setsockopt(zmq.ROUTING_ID, f"joiner-{n}".encode())
                    sock.connect(ta.endpoint)
                    sock.send(f"Hinproc://nowhere-{uuid.uuid4().hex}".encode())
                await eventually(
                    lambda: ta.hellos + ta.stats.unknown_peer == 4, "all hellos handled"
                )
            finally:
                for sock in raw:
                    sock.close(0)
            assert len(ta.peers()) == 2  # the two heard last (arrival order is the network's)
            assert ta.peers() <= {f"joiner-{n}" for n in range(4)}
            assert ta.hellos == 4
            assert ta.stats.unknown_peer == 0


async def test_configured_peers_are_never_evicted_and_a_full_table_refuses() -> None:
    ctx = zmq.asyncio.Context.instance()
    raw: list[zmq.Socket[bytes]] = []
    peers = {"p0": "tcp://127.0.0.1:9", "p1": "tcp://127.0.0.1:9"}
    with anyio.fail_after(5):
        async with zmq_system("a", "tcp://127.0.0.1:*", max_peers=2, peers=peers) as (_a, ta):
            try:
                sock: zmq.Socket[bytes] = zmq.Socket(ctx, zmq.DEALER)
                raw.append(sock)
                sock.setsockopt(zmq.LINGER, 0)
                sock.setsockopt(zmq.ROUTING_ID, b"stranger")
                sock.connect(ta.endpoint)
                sock.send(f"Hinproc://nowhere-{uuid.uuid4().hex}".encode())
                await eventually(lambda: ta.stats.unknown_peer == 1, "the hello refused")
            finally:
                for sock in raw:
                    sock.close(0)
            assert ta.peers() == {"p0", "p1"}
            assert ta.stats.by_reason == {"too many peers": 1}


async def test_a_stranger_that_never_speaks_is_forgotten() -> None:
    ctx = zmq.asyncio.Context.instance()
    with anyio.fail_after(5):
        async with zmq_system("a", "tcp://127.0.0.1:*", stranger_ttl_s=0.05) as (_a, ta):
            sock: zmq.Socket[bytes] = zmq.Socket(ctx, zmq.DEALER)
            try:
                sock.setsockopt(zmq.LINGER, 0)
                sock.setsockopt(zmq.ROUTING_ID, b"ghost")
                sock.connect(ta.endpoint)
                sock.send(f"Hinproc://nowhere-{uuid.uuid4().hex}".encode())
                await eventually(lambda: ta.hellos == 1, "the hello taken")
                assert "ghost" in ta.peers()
                await eventually(lambda: "ghost" not in ta.peers(), "the ghost forgotten")
            finally:
                sock.close(0)


# -- two systems in two OS processes ------------------------------------------------------


@contextlib.asynccontextmanager
async def child_system(system_id: str, bind: str, parent: ZmqTransport) -> AsyncIterator[str]:
    """Run ``peer_process.py`` as another OS process; yield the endpoint it bound.

    The child knows only the parent's endpoint (and says hello to it). It is told to
    quit by closing its stdin, and killed if it does not exit in time.
    """
    args = [sys.executable, str(PEER_SCRIPT), "--id", system_id, "--bind", bind]
    args += ["--peer", f"{parent.system_id}={parent.endpoint}", "--lifetime", "30"]
    process: Process = await anyio.open_process(args, stdin=subprocess.PIPE, stderr=None)
    try:
        assert process.stdout is not None
        with anyio.fail_after(15):
            line = await BufferedByteReceiveStream(process.stdout).receive_until(b"\n", 4096)
        text = line.decode()
        assert text.startswith(READY), text
        yield text[len(READY) :].strip()
        assert process.stdin is not None
        await process.stdin.aclose()
        with anyio.fail_after(5):
            assert await process.wait() == 0
    finally:
        if process.returncode is None:
            process.kill()
            with anyio.CancelScope(shield=True):
                await process.wait()
        await process.aclose()


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["tcp", "ipc"])
async def test_two_processes_round_trips_both_ways(scheme: str, tmp_path: Path) -> None:
    if scheme == "tcp":
        mine, theirs = "tcp://127.0.0.1:*", "tcp://127.0.0.1:*"
    else:
        mine, theirs = f"ipc://{tmp_path}/parent.sock", f"ipc://{tmp_path}/child.sock"
    with anyio.fail_after(20):
        async with (
            zmq_system("parent", mine) as (system, transport),
            child_system("child", theirs, transport) as endpoint,
        ):
            assert endpoint.startswith(f"{scheme}://")
            # Never configured here: the child's hello makes it a peer.
            await eventually(lambda: "child" in transport.peers(), "child said hello")
            assert transport.peer_endpoints()["child"] == endpoint
            child_echo = system.ref(Address("child", "echo"))
            for i in range(20):
                assert await child_echo.ask(Echo(f"{i}")) == Echoed(f"{i}", "child")
            # child -> parent: the child's actor asks our echo and returns the answer.
            for i in range(5):
                reply = await child_echo.ask(Relay(Address("parent", "echo"), f"r{i}"))
                assert reply == Echoed(f"r{i}", "parent")
            assert transport.stats.malformed == transport.stats.unknown_peer == 0


# -- junk on the wire ---------------------------------------------------------------------


def _envelope_bytes(kind: Kind, sender: Address, recipient: Address, msg: Any) -> bytes:
    """Encode an envelope without a registry check (to send unregistered messages)."""
    return msgspec.msgpack.encode(Envelope(kind, sender, recipient, msg, 7))


class _Fuzzer:
    """Makes seeded junk frames (and a few well-formed lies) for one raw DEALER."""

    def __init__(self, rng: random.Random, ident: bytes | None, target: str) -> None:
        self.rng = rng
        self.ident = ident
        self.target = target

    def frames(self) -> list[bytes]:
        rng = self.rng
        me = (self.ident or b"?").decode(errors="replace")
        valid = _envelope_bytes(
            Kind.TELL, Address(me, "x"), Address(self.target, "inbox"), Note("fuzz")
        )
        choices: list[Callable[[], list[bytes]]] = [
            lambda: [rng.randbytes(rng.randrange(0, 300))],
            lambda: [b"M" + rng.randbytes(rng.randrange(0, 300))],
            lambda: [b"M" + valid[: rng.randrange(0, len(valid))]],
            lambda: [b"M" + valid, rng.randbytes(rng.randrange(0, 20))],
            lambda: [rng.randbytes(3) for _ in range(rng.randrange(2, 5))],
            lambda: [b""],
            lambda: [bytes([rng.choice(b"XYZmh\x00\xff")]) + valid],
            lambda: [b"H" + rng.randbytes(rng.randrange(0, 50))],
            lambda: [b"H" + b"tcp://" + bytes([0xFF, 0xFE])],
            lambda: [b"H" + b"http://example.invalid/"],
            lambda: [b"H" + b"tcp://" + b"9" * 5000],
            # A well-formed envelope claiming to come from another system.
            lambda: [
                b"M"
                + _envelope_bytes(
                    Kind.ASK, Address("someone-else", "x"), Address(self.target, "echo"), Echo("s")
                )
            ],
            lambda: [
                b"M"
                + _envelope_bytes(
                    Kind.TELL, Address(me, "x"), Address(self.target, "inbox"), Unregistered(1)
                )
            ],
            lambda: [
                b"M" + _envelope_bytes(Kind.TELL, Address(me, "x"), Address(me, "x"), Note("?"))
            ],
            lambda: [b"M" + msgspec.msgpack.encode([9, ["a", "b"], ["c"], None, "x"])],
            lambda: [b"M" + msgspec.msgpack.encode({"kind": 0})],
            lambda: [b"M" + rng.randbytes(100_000)],
        ]
        return rng.choice(choices)()


async def test_junk_frames_are_dropped_and_counted(
    plain_logs: list[MutableMapping[str, Any]],
) -> None:
    rng = random.Random(20_241_122)
    ctx = zmq.asyncio.Context.instance()
    raw: list[zmq.Socket[bytes]] = []
    # Reader callbacks run outside any task: an exception there would only reach the
    # loop's exception handler, so watch it too.
    loop = asyncio.get_running_loop()
    escaped: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _loop, context: escaped.append(context))
    try:
        await _fire_junk(rng, ctx, raw, plain_logs)
    finally:
        loop.set_exception_handler(None)
    assert not escaped


async def _fire_junk(
    rng: random.Random,
    ctx: zmq.asyncio.Context,
    raw: list[zmq.Socket[bytes]],
    plain_logs: list[MutableMapping[str, Any]],
) -> None:
    with anyio.fail_after(15):
        async with zmq_system("target", "tcp://127.0.0.1:*") as (system, transport):
            try:
                idents: list[bytes | str | None] = [
                    None,  # zmq makes up a NUL-prefixed routing id
                    b"fuzz-known",  # says a valid hello first, then sends junk
                    b"fuzz-unknown",  # never says hello
                    bytes(rng.randrange(1, 256) for _ in range(255)),  # huge, not UTF-8
                    "ü" * 127,  # huge but valid UTF-8
                    b"target",  # the receiver's own id
                    b"*",
                    b"with/slash",
                ]
                fuzzers: list[tuple[zmq.Socket[bytes], _Fuzzer]] = []
                for ident in idents:
                    sock: zmq.Socket[bytes] = zmq.Socket(ctx, zmq.DEALER)
                    raw.append(sock)
                    sock.setsockopt(zmq.LINGER, 0)
                    if ident is not None:
                        rid = ident.encode() if isinstance(ident, str) else ident
                        sock.setsockopt(zmq.ROUTING_ID, rid)
                    else:
                        rid = None
                    sock.connect(transport.endpoint)
                    fuzzers.append((sock, _Fuzzer(rng, rid, "target")))
                frames_sent = 0
                # A valid hello with an endpoint nobody listens on; replies queue there.
                hello_to = f"inproc://nowhere-{uuid.uuid4().hex}".encode()
                raw[1].send(b"H" + hello_to)
                frames_sent += 1
                await eventually(lambda: "fuzz-known" in transport.peers(), "hello accepted")
                for _ in range(300):
                    sock, fuzzer = rng.choice(fuzzers)
                    sock.send_multipart(fuzzer.frames())
                    frames_sent += 1

                # Every frame ends up counted exactly once: delivered, dropped or a hello.
                def handled() -> int:
                    s = transport.stats
                    return s.received + s.malformed + s.unknown_peer + transport.hellos

                await eventually(lambda: handled() >= frames_sent, "every frame handled", 10)
                assert handled() == frames_sent
            finally:
                for sock in raw:
                    sock.close(0)

            stats = transport.stats
            drops = sum(stats.by_reason.values())
            assert drops == stats.malformed + stats.unknown_peer
            assert stats.malformed > 100
            assert stats.unknown_peer > 10
            for reason in (
                "frame count",
                "unknown frame kind",
                "bad envelope",
                "bad hello",
                "sender mismatch",
                "wrong recipient",
                "unknown peer",
            ):
                assert stats.by_reason.get(reason, 0) > 0, reason
            # Only the one good hello made a peer, whatever the junk claimed.
            assert transport.peers() == {"fuzz-known"}
            # Log lines are rate-limited per reason, so junk cannot flood the log.
            dropped_logs = [e for e in plain_logs if e["event"] == "transport.dropped"]
            assert 0 < len(dropped_logs) < drops
            assert not [e for e in plain_logs if e["event"].endswith("_failed")]

            # The receiver is alive and well: a proper peer still gets answers.
            async with zmq_system(
                "probe", "tcp://127.0.0.1:*", peers={"target": transport.endpoint}
            ) as (
                probe,
                _,
            ):
                reply = await probe.ref(Address("target", "echo")).ask(Echo("still there?"))
                assert reply == Echoed("still there?", "target")
                await eventually(lambda: "probe" in transport.peers(), "probe said hello")
                assert await system.ref(Address("probe", "echo")).ask(Echo("yes")) == Echoed(
                    "yes", "probe"
                )


# -- edges --------------------------------------------------------------------------------


async def test_send_to_unknown_system_is_counted_never_raised() -> None:
    with anyio.fail_after(5):
        async with zmq_system("a", "tcp://127.0.0.1:*") as (system, transport):
            env = Envelope(Kind.TELL, system.address, Address("ghost", "x"), Note("boo"))
            transport.send(env)
            system.ref(Address("ghost", "inbox")).tell(Note("boo"))
            assert transport.stats.undeliverable == 2
            assert transport.stats.by_reason == {"no peer ghost": 2}
            # Broadcasting with nobody around is not an error either.
            transport.send(Envelope(Kind.TELL, system.address, Address(BROADCAST, "x"), Note("?")))
            assert transport.stats.sent == 0


async def test_close_is_idempotent_and_ends_serving() -> None:
    reg = registry()
    transport = ZmqTransport("a", "tcp://127.0.0.1:*", reg, peers={"b": "tcp://127.0.0.1:9"})
    try:
        with anyio.fail_after(5):
            async with ActorSystem(transport=transport, registry=reg):
                transport.close()
                transport.close()
                assert transport.closed
                assert transport.peers() == frozenset()
                # Sending after close is still not an error.
                transport.send(Envelope(Kind.TELL, Address("a", "x"), Address("b", "y"), None))
                assert transport.stats.undeliverable == 1
    finally:
        transport.close()
    assert transport.closed
    with pytest.raises(RuntimeError, match="closed"):
        transport.add_peer("c", "tcp://127.0.0.1:9")


async def test_leaving_the_system_closes_the_transport() -> None:
    with anyio.fail_after(5):
        async with zmq_system("a", "tcp://127.0.0.1:*") as (_, transport):
            assert not transport.closed
        assert transport.closed
        with pytest.raises(RuntimeError, match="closed"):
            async with ActorSystem(transport=transport, registry=transport.codec.registry):
                pass


def test_close_without_serving() -> None:
    transport = ZmqTransport("a", "tcp://127.0.0.1:*", registry())
    transport.close()
    transport.close()


@pytest.mark.parametrize(
    "bind",
    [
        "tcp://127.0.0.1:notaport",
        "tcp://256.256.256.256:1",
        "bogus://127.0.0.1:1",
        "ipc:///nonexistent-dir-for-btcap/x.sock",
        "127.0.0.1:5555",
        "tcp://127.0.0.1:65536",  # libzmq would bind port 0 + 1 = 1 instead
        "tcp://:5555",
    ],
)
def test_bad_bind_endpoint_raises_value_error_naming_it(bind: str) -> None:
    with pytest.raises(ValueError, match="cannot bind") as info:
        ZmqTransport("a", bind, registry())
    assert repr(bind) in str(info.value)


def test_endpoint_in_use_raises_value_error() -> None:
    endpoint = f"inproc://in-use-{uuid.uuid4().hex}"
    first = ZmqTransport("a", endpoint, registry())
    try:
        with pytest.raises(ValueError, match=repr(endpoint)):
            ZmqTransport("b", endpoint, registry())
    finally:
        first.close()


@pytest.mark.parametrize("system_id", ["", "*", "a/b", "\x00zmq", "x" * 300])
def test_bad_system_ids_are_refused(system_id: str) -> None:
    with pytest.raises(ValueError, match="system id"):
        ZmqTransport(system_id, "tcp://127.0.0.1:*", registry())
    transport = ZmqTransport("ok", "tcp://127.0.0.1:*", registry())
    try:
        with pytest.raises(ValueError, match="peer id"):
            transport.add_peer(system_id, "tcp://127.0.0.1:9")
        with pytest.raises(ValueError, match="endpoint"):
            transport.add_peer("fine", "127.0.0.1:9")
    finally:
        transport.close()


def test_an_ipc_socket_file_is_removed_on_close(tmp_path: Path) -> None:
    path = tmp_path / "robot.sock"
    transport = ZmqTransport("a", f"ipc://{path}", registry())
    assert path.exists()
    transport.close()
    assert not path.exists()


def test_a_robot_may_hold_more_peers_than_libzmqs_default_socket_limit() -> None:
    """Each peer costs a DEALER and a monitor pair: 400 peers are 1,200 sockets, past the
    1,023 libzmq allows a context by default."""
    ctx: zmq.asyncio.Context = zmq.asyncio.Context()
    t = ZmqTransport("hub", "tcp://127.0.0.1:*", MessageRegistry(), context=ctx)
    try:
        for i in range(400):
            t.add_peer(f"peer-{i}", f"tcp://127.0.0.1:{20000 + i}")
        assert len(t.peers()) == 400
    finally:
        t.close()
        ctx.term()
