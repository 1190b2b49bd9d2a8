"""Several actor systems in one process, joined by an InProcessNetwork."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator, Iterator
from contextlib import AsyncExitStack, asynccontextmanager

import anyio
import pytest
from structlog.testing import capture_logs

from btcap.actors import (
    Actor,
    ActorFailed,
    ActorSystem,
    Address,
    AskTimeout,
    DeadLetter,
    Message,
    SystemClosed,
    handler,
    runtime_messages,
)
from btcap.transports import CodecError, InProcessNetwork, MessageRegistry


@pytest.fixture(autouse=True)
def plain_logs() -> Iterator[None]:
    """Capture log events (cheap) and print them plainly, shown only for a failing test."""
    with capture_logs() as entries:
        yield
    for entry in entries:
        print(entry)


# -- messages and actors ------------------------------------------------------------------


class Ping(Message):
    n: int


class Pong(Message):
    n: int
    by: str


class Note(Message):
    text: str


class Get(Message):
    pass


class Notes(Message):
    texts: list[str]


class Boom(Message):
    why: str


class Hang(Message):
    pass


class BadReply(Message):
    pass


class Unregistered(Message):
    pass


class SendUnregistered(Message):
    pass


class Peer(Actor):
    """Answers pings, records notes, fails and hangs on request."""

    def __init__(self) -> None:
        super().__init__()
        self.notes: list[str] = []
        self.received: list[Message] = []
        self.hanging = asyncio.Event()

    @handler
    def on_ping(self, msg: Ping) -> Pong:
        return Pong(msg.n + 1, by=str(self.address))

    @handler
    def on_note(self, msg: Note) -> None:
        self.received.append(msg)
        self.notes.append(msg.text)

    @handler
    def on_get(self, msg: Get) -> Notes:
        return Notes(list(self.notes))

    @handler
    async def on_boom(self, msg: Boom) -> None:
        await asyncio.sleep(0)
        raise ValueError(msg.why)

    @handler
    async def on_hang(self, msg: Hang) -> None:
        self.hanging.set()
        await asyncio.Event().wait()

    @handler
    def on_bad_reply(self, msg: BadReply) -> int:
        return 42

    @handler
    def on_send_unregistered(self, msg: SendUnregistered) -> Unregistered:
        return Unregistered()


def registry() -> MessageRegistry:
    reg = runtime_messages()
    reg.register(Ping, Pong, Note, Get, Notes, Boom, Hang, BadReply, SendUnregistered)
    return reg


@asynccontextmanager
async def team(
    net: InProcessNetwork, *ids: str, ask_timeout: float = 2.0
) -> AsyncIterator[list[ActorSystem]]:
    """Start one actor system per id on ``net``, each with a Peer at ``peer``."""
    async with AsyncExitStack() as stack:
        systems = []
        for sid in ids:
            system = ActorSystem(transport=net.transport(sid), ask_timeout=ask_timeout)
            await stack.enter_async_context(system)
            system.spawn(Peer(), "peer")
            systems.append(system)
        yield systems


def peer(system: ActorSystem) -> Peer:
    actor = system.lookup("peer")
    assert isinstance(actor, Peer)
    return actor


# -- tell and ask ---------------------------------------------------------------------------


async def test_remote_ask_and_tell_both_ways() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, b):
            pong = await a.ref("b/peer").ask(Ping(1), expect=Pong)
            assert pong == Pong(2, by="b/peer")
            pong = await b.ref(Address("a", "peer")).ask(Ping(10), expect=Pong)
            assert pong == Pong(11, by="a/peer")

            note = Note("hello")
            a.ref("b/peer").tell(note)
            assert peer(b).notes == []  # remote delivery is asynchronous
            reply = await a.ref("b/peer").ask(Get(), expect=Notes)
            assert reply.texts == ["hello"]
            assert peer(b).received[0] == note
            assert peer(b).received[0] is not note  # it went through the codec
            b.ref("a/peer").tell(Note("back"))
            assert (await b.ref("a/peer").ask(Get(), expect=Notes)).texts == ["back"]


async def test_remote_messages_from_one_sender_arrive_in_order() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            ref = a.ref("b/peer")
            for n in range(100):
                ref.tell(Note(str(n)))
            assert (await ref.ask(Get(), expect=Notes)).texts == [str(n) for n in range(100)]


async def test_transport_counters_and_peers() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b", "c") as (a, b, _c):
            assert a.transport is not None
            assert b.transport is not None
            assert a.transport.peers() == frozenset({"b", "c"})
            await a.ref("b/peer").ask(Ping(0))
            assert (a.transport.stats.sent, a.transport.stats.received) == (1, 1)
            assert (b.transport.stats.sent, b.transport.stats.received) == (1, 1)
            a.ref("nowhere/peer").tell(Note("x"))  # no such system on the network
            assert a.transport.stats.undeliverable == 1
            assert a.transport.stats.by_reason == {"no peer nowhere": 1}
        # Systems leave the network when they close.
        assert net.transport("a").peers() == frozenset()


# -- broadcast ------------------------------------------------------------------------------


async def test_broadcast_reaches_every_peer_but_not_self() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b", "c") as (a, b, c):
            a.broadcast("peer", Note("all"))
            for other in ("b", "c"):
                assert (await a.ref(f"{other}/peer").ask(Get(), expect=Notes)).texts == ["all"]
            assert peer(a).notes == []
            a.broadcast("peer", Note("me too"), include_self=True)
            assert peer(a).notes == ["me too"]
            assert (await a.ref("c/peer").ask(Get(), expect=Notes)).texts == ["all", "me too"]
            # A broadcast to a service a system does not host is counted, not a dead letter:
            # systems of a team host different services.
            b.broadcast("nobody-here", Note("lost"))
            await b.ref("a/peer").ask(Ping(0))
            await b.ref("c/peer").ask(Ping(0))
            assert (a.stats.dead_letters, c.stats.dead_letters) == (0, 0)
            assert a.stats.dropped["broadcast_unhandled"] == 1
            assert c.stats.dropped["broadcast_unhandled"] == 1


# -- partitions -----------------------------------------------------------------------------


async def test_isolate_drops_traffic_both_ways_until_heal() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b", "c") as (a, b, c):
            net.isolate("b")
            with pytest.raises(AskTimeout):
                await a.ref("b/peer").ask(Ping(0), timeout=0.02)
            with pytest.raises(AskTimeout):
                await b.ref("a/peer").ask(Ping(0), timeout=0.02)
            a.ref("b/peer").tell(Note("lost"))
            a.broadcast("peer", Note("only c"))
            assert (await a.ref("c/peer").ask(Ping(0), expect=Pong)).n == 1  # a-c unaffected
            assert a.transport is not None
            assert b.transport is not None
            assert a.transport.stats.by_reason["isolated"] == 3  # ask, tell, broadcast to b
            assert b.transport.stats.by_reason["isolated"] == 1
            net.heal("b")
            assert (await a.ref("b/peer").ask(Ping(5), expect=Pong)).n == 6
            assert (await b.ref("a/peer").ask(Ping(7), expect=Pong)).n == 8
            assert peer(b).notes == []  # nothing sent while cut off arrives later
            assert peer(c).notes == ["only c"]


async def test_an_isolated_system_still_reaches_those_it_keeps() -> None:
    """A simulated robot cut off from its team still hears its body (the simulation)."""
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b", "sim") as (a, b, sim):
            net.isolate("b", keep=("sim",))
            assert (await b.ref("sim/peer").ask(Ping(1), expect=Pong)).n == 2
            assert (await sim.ref("b/peer").ask(Ping(3), expect=Pong)).n == 4
            with pytest.raises(AskTimeout):
                await a.ref("b/peer").ask(Ping(0), timeout=0.02)
            with pytest.raises(AskTimeout):
                await b.ref("a/peer").ask(Ping(0), timeout=0.02)
            b.broadcast("peer", Note("to nobody"))  # a broadcast leaves no cut-off system
            sim.broadcast("peer", Note("to a and b"))
            assert (await sim.ref("a/peer").ask(Ping(0), expect=Pong)).n == 1
            assert (await sim.ref("b/peer").ask(Ping(0), expect=Pong)).n == 1
            assert peer(a).notes == ["to a and b"]
            assert peer(b).notes == ["to a and b"]
            assert peer(sim).notes == []
            net.heal("b")
            assert (await a.ref("b/peer").ask(Ping(5), expect=Pong)).n == 6


# -- failures come back typed ---------------------------------------------------------------


async def test_remote_handler_failure_arrives_as_actor_failed() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            with pytest.raises(ActorFailed) as err:
                await a.ref("b/peer").ask(Boom("remote trouble"))
            assert err.value.error_type == "ValueError"
            assert err.value.detail == "remote trouble"
            assert err.value.address == "b/peer"
            assert (await a.ref("b/peer").ask(Ping(1), expect=Pong)).n == 2  # still alive


async def test_ask_to_a_missing_remote_actor_is_a_quick_dead_letter() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        # An ask that ran out of time raises AskTimeout, and only after 60 s (beyond
        # fail_after): a DeadLetter is b's answer, however slowly the machine runs.
        async with team(net, "a", "b", ask_timeout=60.0) as (a, b):
            with pytest.raises(DeadLetter, match="no actor at b/ghost"):
                await a.ref("b/ghost").ask(Ping(0))
            assert b.stats.dead_letters == 1


async def test_a_reply_that_is_not_a_message_becomes_actor_failed() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            with pytest.raises(ActorFailed) as err:
                await a.ref("b/peer").ask(BadReply())
            assert err.value.error_type == "TypeError"
            assert "int is not a Message" in err.value.detail


async def test_a_reply_the_codec_cannot_carry_becomes_actor_failed() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            with pytest.raises(ActorFailed) as err:
                await a.ref("b/peer").ask(SendUnregistered(), timeout=1)
            assert err.value.error_type == "CodecError"
            assert "Unregistered is not registered" in err.value.detail


async def test_sending_an_unregistered_message_fails_at_the_sender() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            with pytest.raises(CodecError, match="Unregistered is not registered"):
                a.ref("b/peer").tell(Unregistered())
            with pytest.raises(CodecError):
                await a.ref("b/peer").ask(Unregistered())
            assert a._pending == {}  # the failed ask left nothing behind


# -- shutdown -------------------------------------------------------------------------------


async def test_pending_remote_ask_fails_with_system_closed_when_the_asker_closes() -> None:
    net = InProcessNetwork(registry())
    before = asyncio.all_tasks()
    with anyio.fail_after(5):
        async with team(net, "b") as (b,):
            async with team(net, "a") as (a,):
                asking = asyncio.create_task(a.ref("b/peer").ask(Hang(), timeout=30))
                await peer(b).hanging.wait()  # b is handling it and will never answer
            with pytest.raises(SystemClosed, match="actor system a shut down"):
                await asking
    assert asyncio.all_tasks() == before


async def test_remote_system_closing_mid_ask_answers_instead_of_timing_out() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a") as (a,):
            async with team(net, "b") as (b,):
                asking = asyncio.create_task(a.ref("b/peer").ask(Hang(), timeout=30))
                await peer(b).hanging.wait()
            with pytest.raises(ActorFailed) as err:
                await asking
            assert err.value.error_type == "SystemClosed"


# -- the network itself ---------------------------------------------------------------------


def test_network_rejects_duplicate_and_reserved_ids() -> None:
    net = InProcessNetwork()
    net.transport("a")
    with pytest.raises(ValueError, match="'a' is already on this network"):
        net.transport("a")
    with pytest.raises(ValueError, match="reserved"):
        net.transport("*")


async def test_unencoded_network_hands_over_the_same_objects() -> None:
    net = InProcessNetwork(encode=False)
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, b):
            note = Note("shared")
            a.ref("b/peer").tell(note)
            await a.ref("b/peer").ask(Get())
            assert peer(b).received == [note]
            assert peer(b).received[0] is note


# -- ask deadlines: one loop timer for every pending ask -----------------------------------


async def test_a_shorter_ask_limit_fires_before_a_longer_one_armed_first() -> None:
    """Remote asks share one timer armed at the soonest deadline: a later ask with a
    shorter limit must move it earlier, and the longer ask still time out after it."""
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            net.isolate("b")
            slow = asyncio.ensure_future(a.ref("b/peer").ask(Ping(0), timeout=0.6))
            await asyncio.sleep(0)
            assert a.pending_asks == 1
            with pytest.raises(AskTimeout, match=r"within 0\.02 s"):
                await a.ref("b/peer").ask(Ping(1), timeout=0.02)
            assert not slow.done()
            assert a.pending_asks == 1
            with pytest.raises(AskTimeout, match=r"within 0\.6 s"):
                await slow
            assert a.pending_asks == 0
            net.heal("b")
            # Answered asks are never failed by the shared timer, and it still re-arms.
            for n in range(3):
                assert (await a.ref("b/peer").ask(Ping(n), timeout=0.05, expect=Pong)).n == n + 1
            net.isolate("b")
            with pytest.raises(AskTimeout):
                await a.ref("b/peer").ask(Ping(0), timeout=0.02)


async def test_a_cancelled_remote_ask_leaves_nothing_pending() -> None:
    net = InProcessNetwork(registry())
    with anyio.fail_after(5):
        async with team(net, "a", "b") as (a, _b):
            net.isolate("b")
            task = asyncio.ensure_future(a.ref("b/peer").ask(Ping(0), timeout=30))
            await asyncio.sleep(0)
            assert a.pending_asks == 1
            task.cancel()
            with pytest.raises(asyncio.CancelledError):
                await task
            assert a.pending_asks == 0
