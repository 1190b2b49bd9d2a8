"""The transport's tuned ZeroMQ context and receive path: I/O threads under SCHED_BATCH,
and asks over tcp on uvloop (the optional ``fast`` extra) as on the stock loop."""

from __future__ import annotations

import asyncio
import os
import sys
import time
from collections.abc import Iterator

import anyio
import pytest
import zmq

from btcap.actors import ActorSystem, Address
from btcap.transports import ZmqTransport
from tests.transports.peer_process import Echo, EchoActor, Echoed, messages

linux_only = pytest.mark.skipif(sys.platform != "linux", reason="SCHED_BATCH is Linux's")


def _io_threads() -> dict[int, int]:
    """ZeroMQ I/O threads of this process: thread id -> scheduling policy."""
    found = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/comm") as f:
                name = f.read().strip()
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        if name.startswith("ZMQbg/IO"):
            found[int(tid)] = int(fields[38])  # field 41 of stat(5): policy
    return found


def _new_io_policies(ctx: zmq.Context[zmq.Socket[bytes]]) -> set[int]:
    before = _io_threads()
    transport = ZmqTransport("a", "tcp://127.0.0.1:*", messages(), context=ctx)
    try:
        # A thread names itself once running, after libzmq has set its policy.
        deadline = time.monotonic() + 5.0
        while not (new := {t: p for t, p in _io_threads().items() if t not in before}):
            assert time.monotonic() < deadline, "the transport's context started no I/O thread"
            time.sleep(0.005)
    finally:
        transport.close()
    return set(new.values())


@pytest.fixture
def context() -> Iterator[zmq.Context[zmq.Socket[bytes]]]:
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context()
    try:
        yield ctx
    finally:
        ctx.term()


@linux_only
def test_io_threads_run_under_sched_batch(context: zmq.Context[zmq.Socket[bytes]]) -> None:
    assert _new_io_policies(context) == {os.SCHED_BATCH}


@linux_only
def test_the_environment_can_keep_the_normal_policy(
    context: zmq.Context[zmq.Socket[bytes]], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("BTCAP_ZMQ_NO_BATCH", "1")
    assert _new_io_policies(context) == {os.SCHED_OTHER}


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
