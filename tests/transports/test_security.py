"""Transport security: CURVE + ZAP against the team's keys, who a sender is, size limits,
the loopback-only default and ``btcap keys new``.

Loopback only (OS-chosen tcp ports); every transport and raw socket is closed.
"""

from __future__ import annotations

import asyncio
import contextlib
import shutil
from collections.abc import AsyncIterator, Callable, Iterator
from pathlib import Path
from typing import Any

import anyio
import msgspec
import pytest
import zmq
from structlog.testing import capture_logs

from btcap.actors import ActorSystem, Address
from btcap.cli import keys as keys_cli
from btcap.cli import main as btcap_main
from btcap.transports import Envelope, KeyPair, Kind, TeamKeys, ZmqTransport, identity
from btcap.transports.security import write_key_pair
from tests.transports.peer_process import Echo, EchoActor, Echoed, messages

LOCAL = "tcp://127.0.0.1:*"


@pytest.fixture(autouse=True)
def quiet_logs() -> Iterator[None]:
    with capture_logs():
        yield


@pytest.fixture
def keys(tmp_path: Path) -> Path:
    """Key pairs for a, b, mallory (members) and outsider; team/ holds the members'."""
    team = tmp_path / "team"
    team.mkdir()
    for name in ("a", "b", "mallory", "outsider"):
        public, _ = write_key_pair(tmp_path, name)
        if name != "outsider":
            shutil.copy(public, team / public.name)
    return tmp_path


def secure(name: str, keys: Path, **kwargs: Any) -> ZmqTransport:
    return ZmqTransport(
        name, LOCAL, messages(), keys=keys / f"{name}.key_secret", trusted=keys / "team", **kwargs
    )


@contextlib.asynccontextmanager
async def serving(transport: ZmqTransport) -> AsyncIterator[ActorSystem]:
    reg = transport.codec.registry
    try:
        async with ActorSystem(transport=transport, registry=reg, ask_timeout=5.0) as system:
            system.spawn(EchoActor(), "echo")
            yield system
    finally:
        transport.close()


async def eventually(predicate: Callable[[], bool], what: str) -> None:
    with anyio.fail_after(5):
        while not predicate():  # noqa: ASYNC110 - counters have no event to wait on
            await anyio.sleep(0.005)
    assert predicate(), what


@contextlib.contextmanager
def raw_dealer(
    routing_id: bytes, endpoint: str, curve: tuple[KeyPair, bytes] | None
) -> Iterator[zmq.Socket[bytes]]:
    """A hand-made client: an attacker's socket (its own context, closed on exit)."""
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    sock = ctx.socket(zmq.DEALER)
    try:
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.ROUTING_ID, routing_id)
        if curve is not None:
            pair, server = curve
            sock.setsockopt(zmq.CURVE_SERVERKEY, server)
            sock.setsockopt(zmq.CURVE_PUBLICKEY, pair.public)
            sock.setsockopt(zmq.CURVE_SECRETKEY, pair.secret)
        sock.connect(endpoint)
        yield sock
    finally:
        sock.close(0)
        ctx.term()


# ZMTP 3.0 greeting of a client offering the NULL mechanism (no key), written by hand.
NULL_GREETING = b"\xff" + bytes(8) + b"\x7f" + b"\x03\x00" + b"NULL".ljust(20, b"\0") + bytes(32)


@contextlib.asynccontextmanager
async def zmtp_connection(
    endpoint: str,
) -> AsyncIterator[tuple[asyncio.StreamReader, asyncio.StreamWriter]]:
    """A bare tcp connection to a transport, for speaking ZMTP by hand (closed on exit)."""
    host, port = endpoint[len("tcp://") :].rsplit(":", 1)
    reader, writer = await asyncio.open_connection(host, int(port))
    try:
        yield reader, writer
    finally:
        writer.close()
        with contextlib.suppress(ConnectionError):
            await writer.wait_closed()


def envelope(sender: str, to: str, text: str) -> bytes:
    env = Envelope(Kind.TELL, Address(sender, "x"), Address(to, "echo"), Echo(text), 1)
    return b"M" + msgspec.msgpack.encode(env)


async def test_members_with_keys_ask_each_other_over_tcp(keys: Path) -> None:
    with anyio.fail_after(10):
        async with contextlib.AsyncExitStack() as stack:
            ta = secure("a", keys)
            a = await stack.enter_async_context(serving(ta))
            tb = secure("b", keys, peers={"a": ta.endpoint})
            b = await stack.enter_async_context(serving(tb))
            assert await b.ref(Address("a", "echo")).ask(Echo("hi a")) == Echoed("hi a", "a")
            await eventually(lambda: "b" in ta.peers(), "a learnt b from its hello")
            assert await a.ref(Address("b", "echo")).ask(Echo("hi b")) == Echoed("hi b", "b")
            assert ta.stats.malformed == tb.stats.malformed == 0


async def test_an_outsider_fails_the_handshake_and_leaves_no_peer_state(keys: Path) -> None:
    """A stranger's key (or no key) gets nothing delivered and opens no socket back.

    A keyless libzmq client races the server to notice the mechanism mismatch: when it
    hangs up first the server sees only a disconnect. The plain greeting written by hand
    stays connected, so the server's own verdict is what is counted, every time.
    """
    outsider = KeyPair.load(keys / "outsider.key_secret")
    with anyio.fail_after(10):
        ta = secure("a", keys)
        async with serving(ta):
            assert ta.curve is not None
            server = ta.curve.keys.public
            with (
                raw_dealer(b"outsider", ta.endpoint, (outsider, server)) as stranger,
                raw_dealer(b"plain", ta.endpoint, None) as plain,
            ):
                for sock, name in ((stranger, "outsider"), (plain, "plain")):
                    sock.send(b"Htcp://127.0.0.1:1")
                    sock.send(envelope(name, "a", "let me in"))
                async with zmtp_connection(ta.endpoint) as (_, writer):
                    writer.write(NULL_GREETING)
                    await writer.drain()
                    await eventually(
                        lambda: (
                            ta.stats.by_reason.get("handshake refused", 0) >= 1
                            and ta.stats.by_reason.get("handshake failed", 0) >= 1
                        ),
                        "the stranger's key refused, the keyless greeting failed",
                    )
            assert ta.stats.received == 0
            assert ta.hellos == 0
            assert ta.peers() == frozenset()
            assert ta.stats.unknown_peer >= 1


async def test_a_member_speaking_for_another_is_dropped_and_counted(keys: Path) -> None:
    """mallory is on the allow-list: neither her routing id nor her envelopes make her b."""
    mallory = KeyPair.load(keys / "mallory.key_secret")
    with anyio.fail_after(10):
        ta = secure("a", keys)
        async with serving(ta), contextlib.AsyncExitStack() as stack:
            assert ta.curve is not None
            server = ta.curve.keys.public
            as_b = stack.enter_context(raw_dealer(b"b", ta.endpoint, (mallory, server)))
            as_me = stack.enter_context(raw_dealer(b"mallory", ta.endpoint, (mallory, server)))
            as_b.send(b"Htcp://127.0.0.1:1")
            as_b.send(envelope("b", "a", "I am b"))
            await eventually(
                lambda: ta.stats.by_reason.get("identity mismatch", 0) == 2, "routing id lie"
            )
            as_me.send(b"H" + ta.endpoint.encode())  # an honest hello: mallory is a member
            await eventually(lambda: "mallory" in ta.peers(), "mallory's own hello accepted")
            as_me.send(envelope("b", "a", "b says so"))
            await eventually(
                lambda: ta.stats.by_reason.get("sender mismatch", 0) == 1, "envelope lie"
            )
            assert "b" not in ta.peers()
            assert ta.stats.received == 0
            assert ta.stats.malformed == 3


async def test_a_member_cannot_take_over_another_members_connection(keys: Path) -> None:
    """mallory connects with b's very routing id (as if she had learnt it): her link is
    refused, b's stays up and b's messages still arrive as b's."""
    mallory = KeyPair.load(keys / "mallory.key_secret")
    with anyio.fail_after(10):
        async with contextlib.AsyncExitStack() as stack:
            ta = secure("a", keys)
            await stack.enter_async_context(serving(ta))
            tb = secure("b", keys, peers={"a": ta.endpoint})
            b = await stack.enter_async_context(serving(tb))
            echo = b.ref(Address("a", "echo"))
            assert await echo.ask(Echo("before")) == Echoed("before", "a")
            b_id = tb.routing_id("a")
            assert b_id.startswith(b"b/")
            assert ta.curve is not None
            as_b = stack.enter_context(
                raw_dealer(b_id, ta.endpoint, (mallory, ta.curve.keys.public))
            )
            events = as_b.get_monitor_socket(zmq.EVENT_HANDSHAKE_SUCCEEDED)
            stack.callback(events.close, 0)
            stack.callback(as_b.disable_monitor)
            await eventually(lambda: events.poll(0) != 0, "mallory's handshake completes")
            as_b.send(envelope("b", "a", "I am b"))
            received = ta.stats.received
            for i in range(3):
                assert await echo.ask(Echo(f"after {i}")) == Echoed(f"after {i}", "a")
            assert ta.stats.received == received + 3
            assert ta.disconnects == 0


async def test_an_oversized_frame_is_cut_off_at_its_header() -> None:
    """A frame header announcing 200 MB closes the connection at once: libzmq never
    allocates or waits for the body (ZMTP 3.0 by hand, so the sender holds no 200 MB)."""
    ta = ZmqTransport("a", LOCAL, messages(), max_message_bytes=64 * 1024)
    async with serving(ta):
        with anyio.fail_after(5):
            async with zmtp_connection(ta.endpoint) as (reader, writer):
                ready = b"\x05READY" + b"\x0bSocket-Type" + (6).to_bytes(4, "big") + b"DEALER"
                writer.write(NULL_GREETING + b"\x04" + bytes([len(ready)]) + ready)
                writer.write(b"\x02" + (200 * 1024 * 1024).to_bytes(8, "big") + b"M" * 100)
                await writer.drain()
                await reader.read(64)  # the peer's greeting
                while await reader.read(65536):  # then EOF: the connection is cut
                    pass
        await eventually(lambda: ta.disconnects == 1, "the cut is counted")
        assert ta.stats.received == 0


async def test_oversized_sends_are_refused_locally() -> None:
    with anyio.fail_after(10):
        async with contextlib.AsyncExitStack() as stack:
            ta = ZmqTransport("a", LOCAL, messages(), max_message_bytes=4096)
            await stack.enter_async_context(serving(ta))
            tb = ZmqTransport(
                "b", LOCAL, messages(), peers={"a": ta.endpoint}, max_message_bytes=4096
            )
            b = await stack.enter_async_context(serving(tb))
            b.ref(Address("a", "echo")).tell(Echo("x" * 5000))
            assert tb.stats.by_reason == {"too large to send": 1}
            assert await b.ref(Address("a", "echo")).ask(Echo("small")) == Echoed("small", "a")


def test_without_keys_only_loopback_binds_unless_insecure(tmp_path: Path) -> None:
    for bind in ("tcp://0.0.0.0:*", "tcp://*:*", "tcp://[::]:*", "tcp://eth0:*"):
        with pytest.raises(ValueError, match="without keys"):
            ZmqTransport("a", bind, messages())
    for bind in ("tcp://127.0.0.1:*", "tcp://localhost:*", f"ipc://{tmp_path}/a.sock"):
        ZmqTransport("a", bind, messages()).close()
    ZmqTransport("a", "tcp://0.0.0.0:*", messages(), insecure=True).close()


def test_key_arguments_are_checked(keys: Path) -> None:
    reg = messages()
    with pytest.raises(ValueError, match="go together"):
        ZmqTransport("a", LOCAL, reg, keys=keys / "a.key_secret")
    with pytest.raises(ValueError, match="not the team's certificate"):
        ZmqTransport("b", LOCAL, reg, keys=keys / "a.key_secret", trusted=keys / "team")
    with pytest.raises(ValueError, match="no secret key"):
        ZmqTransport("a", LOCAL, reg, keys=keys / "a.key", trusted=keys / "team")
    with pytest.raises(ValueError, match="inproc"):
        ZmqTransport("a", "inproc://x", reg, keys=keys / "a.key_secret", trusted=keys / "team")
    with pytest.raises(ValueError, match="no public key"):
        secure("a", keys, peers={"outsider": "tcp://127.0.0.1:1"})
    assert set(TeamKeys.load(keys / "team")) == {"a", "b", "mallory"}


def test_keys_new_writes_loadable_certificates_and_never_overwrites(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert btcap_main(["keys", "new", "robot-1", "--role", "robot", "--dir", str(tmp_path)]) == 0
    pair = KeyPair.load(tmp_path / "robot-1.key_secret")
    assert TeamKeys.load(tmp_path).key_of("robot-1") == pair.public
    assert TeamKeys.load(tmp_path).role_of("robot-1") == "robot"
    assert keys_cli.ROLES == identity.ROLES
    assert (tmp_path / "robot-1.key_secret").stat().st_mode & 0o077 == 0
    before = (tmp_path / "robot-1.key_secret").read_bytes()
    capsys.readouterr()
    assert btcap_main(["keys", "new", "robot-1", "--role", "robot", "--dir", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (tmp_path / "robot-1.key_secret").read_bytes() == before
    missing = str(tmp_path / "missing")
    assert btcap_main(["keys", "new", "x", "--role", "observer", "--dir", missing]) == 2
    assert "no such directory" in capsys.readouterr().err
