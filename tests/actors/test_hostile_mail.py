"""Mail a peer can send without limit costs a counter, not a log line each: unhandled
types, dead letters and messages that make a handler raise are all counted, logged while
``worth_logging`` says so, and only the first failure of a kind carries a traceback."""

from __future__ import annotations

from typing import Any

import anyio
from structlog.testing import capture_logs

from btcap.actors import Actor, ActorSystem, Supervision, handler
from btcap.transports import Address, InProcessNetwork, Message, MessageRegistry
from btcap.transports.base import TransportStats

FLOOD = 5_000
# worth_logging: the first ten, then every power of two up to FLOOD.
LINES = 10 + sum(1 for k in range(4, 13) if 2**k <= FLOOD)


class Ping(Message):
    n: int


class Other(Message):
    text: str


class Picky(Actor):
    supervision = Supervision.RESUME

    def __init__(self) -> None:
        super().__init__()
        self.good = 0

    @handler
    def on_ping(self, msg: Ping) -> Ping:
        if msg.n < 0:
            raise ValueError(f"negative {msg.n}")
        self.good += 1
        return Ping(self.good)


def net_stats(system: ActorSystem) -> TransportStats:
    assert system.transport is not None
    return system.transport.stats


async def flood(msg: Message, to: str) -> tuple[ActorSystem, Picky, list[dict[str, Any]]]:
    registry = MessageRegistry([Ping, Other])
    net = InProcessNetwork(registry)
    with capture_logs() as logs:
        async with (
            ActorSystem("robot", transport=net.transport("robot"), registry=registry) as robot,
            ActorSystem("peer", transport=net.transport("peer"), registry=registry) as peer,
        ):
            picky = Picky()
            robot.spawn(picky, "picky")
            for _ in range(FLOOD):
                peer.tell(Address("robot", to), msg)
            # Delivered in order: the answer comes after the flood, and at once.
            assert await peer.ask(Address("robot", "picky"), Ping(1), timeout=1) == Ping(1)
            assert net_stats(robot).received == FLOOD + 1
    return robot, picky, logs


async def test_a_flood_of_unhandled_messages_is_counted_and_logged_sparingly() -> None:
    with anyio.fail_after(10):
        robot, _picky, logs = await flood(Other("junk"), "picky")
    assert robot.stats.dropped == {"unhandled": FLOOD}
    lines = [e for e in logs if e["event"] == "actors.dropped"]
    assert len(lines) == LINES
    assert lines[-1]["count"] == 4096


async def test_a_flood_of_dead_letters_is_counted_and_logged_sparingly() -> None:
    with anyio.fail_after(10):
        robot, _picky, logs = await flood(Ping(1), "nobody")
    assert robot.stats.dead_letters == FLOOD
    assert len([e for e in logs if e["event"] == "actors.dead_letter"]) == LINES


async def test_a_flood_that_makes_a_handler_raise_logs_one_traceback() -> None:
    with anyio.fail_after(10):
        robot, picky, logs = await flood(Ping(-1), "picky")
    assert robot.stats.failures == {"Picky: Ping: ValueError": FLOOD}
    assert picky.good == 1
    lines = [e for e in logs if e["event"] == "actor.handler_failed"]
    assert len(lines) == LINES
    assert isinstance(lines[0]["exc_info"], ValueError)
    assert all("exc_info" not in e and e["error"] == "negative -1" for e in lines[1:])
    assert {e["sender"] for e in lines} == {"peer"}
