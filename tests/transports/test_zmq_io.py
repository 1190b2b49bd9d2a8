"""Asks over tcp on uvloop (the optional ``fast`` extra) as on the stock loop."""

from __future__ import annotations

import asyncio

import anyio
import pytest

from btcap.actors import ActorSystem, Address
from btcap.transports import ZmqTransport
from tests.transports.peer_process import Echo, EchoActor, Echoed, messages


async def _ask_over_tcp() -> list[int]:
    with anyio.fail_after(10):
        tb = ZmqTransport("b", "tcp://127.0.0.1:*", messages())
        ta = ZmqTransport("a", "tcp://127.0.0.1:*", messages(), peers={"b": tb.endpoint})
        async with (
            ActorSystem(transport=tb, registry=messages()) as b,
            ActorSystem(transport=ta, registry=messages()) as a,
        ):
            b.spawn(EchoActor(), "echo")
            ref = a.ref(Address("b", "echo"))
            replies = [await ref.ask(Echo(str(i)), expect=Echoed) for i in range(50)]
            return [int(r.text) for r in replies]


def test_asks_over_tcp_on_the_stock_loop() -> None:
    assert asyncio.run(_ask_over_tcp()) == list(range(50))


def test_asks_over_tcp_on_uvloop() -> None:
    uvloop = pytest.importorskip("uvloop")
    assert uvloop.run(_ask_over_tcp()) == list(range(50))
