"""``@handler(local_only=True)``: a message the actor takes only from its own system.

From a transport it is refused whatever sender the envelope names, counted by kind in
``SystemStats.refused``, logged once per sender and kind, and an ask is answered with
``Refused``; from inside the system (tell, ask, the fast path, the mailbox, another
actor) it is handled as any other message.
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

import anyio
import pytest
from anyio.abc import TaskStatus
from structlog.testing import capture_logs

from btcap.actors import Actor, ActorFailed, ActorSystem, Refused, handler
from btcap.actors.refusals import OTHERS, Refusals
from btcap.transports import (
    BROADCAST,
    Address,
    Deliver,
    Envelope,
    InProcessNetwork,
    Kind,
    Message,
    MessageRegistry,
    Transport,
    TransportStats,
)
from btcap.transports.log import get_logger


class Poke(Message):
    n: int = 0


class Prod(Message):
    pass


class Read(Message):
    pass


class Guarded(Actor):
    """Poke only from inside (annotated), Prod only from inside (named, async), Read from
    anyone."""

    def __init__(self) -> None:
        super().__init__()
        self.pokes: list[int] = []
        self.prods = 0

    @handler(local_only=True)
    def on_poke(self, msg: Poke) -> Poke:
        self.pokes.append(msg.n)
        return Poke(len(self.pokes))

    @handler(Prod, local_only=True)
    async def on_prod(self, msg: Any) -> Prod:
        await asyncio.sleep(0)
        self.prods += 1
        return Prod()

    @handler
    def on_read(self, msg: Read) -> Poke:
        return Poke(len(self.pokes))


class Forwarder(Actor):
    """Another actor of the same system passing a Poke on."""

    @handler
    def on_read(self, msg: Read) -> None:
        self.system.ref("guarded").tell(Poke(7))


def registry() -> MessageRegistry:
    return MessageRegistry([Poke, Prod, Read])


@asynccontextmanager
async def pair() -> AsyncIterator[tuple[ActorSystem, ActorSystem, Guarded]]:
    reg = registry()
    net = InProcessNetwork(reg)
    async with (
        ActorSystem("robot", transport=net.transport("robot"), registry=reg) as robot,
        ActorSystem("peer", transport=net.transport("peer"), registry=reg) as peer,
    ):
        guarded = Guarded()
        robot.spawn(guarded, "guarded")
        yield robot, peer, guarded


def refusal_lines(logs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [e for e in logs if e["event"] == "actors.refused"]


async def test_local_only_messages_are_handled_from_inside_the_system() -> None:
    with anyio.fail_after(5):
        async with pair() as (robot, _peer, guarded):
            ref = robot.ref("guarded")
            ref.tell(Poke(1))  # the direct call of an idle actor
            assert await ref.ask(Poke(2)) == Poke(2)  # the ask fast path
            assert await robot.ask(Address("robot", "guarded"), Poke(3)) == Poke(3)
            assert await ref.ask(Prod()) == Prod()  # async: through the mailbox
            robot.spawn(Forwarder(), "forwarder")
            robot.ref("forwarder").tell(Read())
            assert guarded.pokes == [1, 2, 3, 7]
            assert guarded.prods == 1
            assert robot.stats.refused == {}


async def test_from_another_system_they_are_refused_counted_and_logged_once() -> None:
    with anyio.fail_after(5):
        async with pair() as (robot, peer, guarded):
            target = Address("robot", "guarded")
            with capture_logs() as logs:
                for n in range(3):
                    with pytest.raises(ActorFailed) as info:
                        await peer.ask(target, Poke(n), timeout=1)
                    assert info.value.error_type == Refused.__qualname__
                    assert "Poke to robot/guarded is taken only from inside robot" in str(
                        info.value
                    )
                peer.tell(target, Poke(9))
                with pytest.raises(ActorFailed, match="Refused"):
                    await peer.ask(target, Prod(), timeout=1)
                peer.broadcast("guarded", Poke(10))
                # What others may send still gets through, after the refused mail.
                assert await peer.ask(target, Read(), timeout=1) == Poke(0)
            assert guarded.pokes == []
            assert guarded.prods == 0
            assert robot.stats.refused == {"Poke": 5, "Prod": 1}
            lines = refusal_lines(logs)
            assert [(e["sender"], e["message"], e["to"], e["count"]) for e in lines] == [
                ("peer", "Poke", "robot/guarded", 1),
                ("peer", "Prod", "robot/guarded", 1),
            ]
            assert all(e["log_level"] == "warning" for e in lines)
            assert robot.stats.dropped == {}


async def test_each_sender_gets_its_own_line() -> None:
    with anyio.fail_after(5):
        reg = registry()
        net = InProcessNetwork(reg)
        async with (
            ActorSystem("robot", transport=net.transport("robot"), registry=reg) as robot,
            ActorSystem("eve", transport=net.transport("eve"), registry=reg) as eve,
            ActorSystem("mal", transport=net.transport("mal"), registry=reg) as mal,
        ):
            robot.spawn(Guarded(), "guarded")
            with capture_logs() as logs:
                for system in (eve, mal, eve, mal):
                    system.tell(Address("robot", "guarded"), Poke())
                await eve.ask(Address("robot", "guarded"), Read(), timeout=1)
                await mal.ask(Address("robot", "guarded"), Read(), timeout=1)
            assert [e["sender"] for e in refusal_lines(logs)] == ["eve", "mal"]
            assert robot.stats.refused == {"Poke": 4}


class Wire(Transport):
    """A transport a test feeds by hand: it can claim any sender, as a keyless peer can."""

    def __init__(self, system_id: str) -> None:
        self.system_id = system_id
        self.stats = TransportStats()
        self.deliver: Deliver | None = None
        self.sent: list[Envelope] = []

    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        self.deliver = deliver
        task_status.started()
        await anyio.sleep_forever()

    def send(self, env: Envelope) -> None:
        self.sent.append(env)

    def peers(self) -> frozenset[str]:
        return frozenset()


@pytest.mark.parametrize("claimed", ["robot", "peer", BROADCAST])
async def test_refused_whatever_sender_the_envelope_names(claimed: str) -> None:
    """Even mail that names this very system as its sender came through a transport."""
    with anyio.fail_after(5):
        wire = Wire("robot")
        async with ActorSystem(transport=wire, registry=registry()) as robot:
            guarded = Guarded()
            robot.spawn(guarded, "guarded")
            assert wire.deliver is not None
            env = Envelope(Kind.ASK, Address(claimed, "x"), Address("robot", "guarded"), Poke(), 7)
            wire.deliver(env)
            assert guarded.pokes == []
            assert robot.stats.refused == {"Poke": 1}
            [reply] = wire.sent
            assert reply.kind is Kind.FAIL
            assert reply.corr == 7
            assert reply.recipient == Address(claimed, "x")
            assert reply.msg.error_type == "Refused"


def test_the_table_of_senders_is_bounded() -> None:
    refusals = Refusals("robot", get_logger("btcap.actors.refusals"), limit=3)
    assert refusals.count("a", "Tick") == ("a", 1)
    assert refusals.count("a", "Tick") == ("a", 2)
    assert refusals.count("b", "Tick") == ("b", 1)
    assert refusals.count("c", "Reset") == ("c", 1)
    # Full: newcomers share one count per kind; known pairs go on counting.
    assert refusals.count("d", "Tick") == (OTHERS, 1)
    assert refusals.count("e", "Tick") == (OTHERS, 2)
    assert refusals.count("a", "Tick") == ("a", 3)
    assert len(refusals) == 4
    for n in range(1, 5000):
        refusals.count(f"ghost-{n}", "Tick")
    assert len(refusals) == 4


async def test_past_the_bound_newcomers_are_logged_as_others() -> None:
    with anyio.fail_after(5):
        async with pair() as (robot, peer, _guarded):
            robot._refusals.limit = 0  # every sender is a newcomer past the bound
            with capture_logs() as logs:
                for _ in range(2):
                    peer.tell(Address("robot", "guarded"), Poke())
                await peer.ask(Address("robot", "guarded"), Read(), timeout=1)
            [line] = refusal_lines(logs)
            assert (line["sender"], line["counted_as"], line["count"]) == ("peer", OTHERS, 1)
            assert robot.stats.refused == {"Poke": 2}


def test_a_pair_is_logged_first_then_rarely() -> None:
    logged = [n for n in range(1, 5000) if Refusals.worth_logging(n)]
    assert logged == [1, 1024, 2048, 4096]
