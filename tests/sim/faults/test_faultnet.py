"""The seeded faulty network of ``btcap sim-test``: each fault really happens, through the
codec, on the virtual clock, and the same seed makes the same faults."""

from __future__ import annotations

import random
from collections.abc import Callable

import anyio
import pytest
from anyio.abc import TaskStatus

from btcap.actors import ManualClock
from btcap.sim.faults.network import FaultyNetwork, FaultyTransport, LinkFaults
from btcap.team.messages import Goodbye
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import BROADCAST, Address
from btcap.transports.codec import Envelope, Kind

Got = list[tuple[float, str, int]]  # (clock time, receiver, message number)


def _env(src: str, dest: str, n: int) -> Envelope:
    return Envelope(Kind.TELL, Address(src, "team"), Address(dest, "team"), Goodbye(src, n))


async def _with_net(
    seed: int, names: list[str], body: Callable[[FaultyNetwork, dict[str, FaultyTransport]], object]
) -> Got:
    """Ports for ``names`` serving on a manual clock; ``body`` sends; what arrived, when."""
    clock = ManualClock()
    net = FaultyNetwork(clock, random.Random(seed), protocol_registry())
    got: Got = []
    ports = {name: net.transport(name) for name in names}
    with anyio.fail_after(10):
        async with anyio.create_task_group() as tg:
            for name, port in ports.items():

                def deliver(env: Envelope, name: str = name) -> None:
                    assert isinstance(env.msg, Goodbye)
                    got.append((clock.now(), name, env.msg.incarnation))

                async def serve(
                    port: FaultyTransport = port,
                    deliver: Callable[[Envelope], None] = deliver,
                    *,
                    task_status: TaskStatus[None] = anyio.TASK_STATUS_IGNORED,
                ) -> None:
                    await port.serve(deliver, task_status=task_status)

                await tg.start(serve)
            body(net, ports)
            await clock.advance(10.0)
            tg.cancel_scope.cancel()
    return got


def _send_many(count: int = 200) -> Callable[[FaultyNetwork, dict[str, FaultyTransport]], None]:
    def body(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        for n in range(count):
            ports["a"].send(_env("a", "b", n))

    return body


async def test_a_clean_network_delivers_everything_in_order_at_once() -> None:
    got = await _with_net(1, ["a", "b"], _send_many())
    assert [n for _, _, n in got] == list(range(200))
    assert {t for t, _, _ in got} == {0.0}


async def test_drops_duplicates_and_delays_happen_as_the_rates_say() -> None:
    def faulty(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.faults = LinkFaults(drop=0.2, duplicate=0.2, delay=0.5, max_delay_s=1.0)
        _send_many(1000)(net, ports)

    got = await _with_net(7, ["a", "b"], faulty)
    numbers = [n for _, _, n in got]
    c_missing = 1000 - len(set(numbers))
    assert 150 < c_missing < 250  # about a fifth dropped
    assert 100 < len(numbers) - len(set(numbers)) < 220  # about a fifth of the rest twice
    late = [t for t, _, _ in got if t > 0]
    assert late
    assert max(late) <= 1.0
    assert numbers != sorted(numbers)  # so reordered


async def test_the_same_seed_makes_the_same_faults() -> None:
    def faulty(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.faults = LinkFaults(drop=0.3, duplicate=0.3, delay=0.5, max_delay_s=0.5)
        _send_many(300)(net, ports)

    one = await _with_net(5, ["a", "b"], faulty)
    assert one == await _with_net(5, ["a", "b"], faulty)
    assert one != await _with_net(6, ["a", "b"], faulty)


async def test_a_partition_cuts_between_groups_only_until_healed() -> None:
    def body(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.partition([["a", "b"], ["c"]])
        ports["a"].send(
            Envelope(Kind.TELL, Address("a", "team"), Address(BROADCAST, "team"), Goodbye("a", 1))
        )
        ports["c"].send(_env("c", "a", 2))
        net.heal()
        ports["c"].send(_env("c", "a", 3))

    got = await _with_net(1, ["a", "b", "c"], body)
    assert sorted((who, n) for _, who, n in got) == [("a", 3), ("b", 1)]


async def test_a_one_way_cut_loses_one_direction_only() -> None:
    def body(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.cut_oneway("a", "b")
        ports["a"].send(_env("a", "b", 1))
        ports["b"].send(_env("b", "a", 2))
        net.heal()
        ports["a"].send(_env("a", "b", 3))

    got = await _with_net(1, ["a", "b"], body)
    assert [(who, n) for _, who, n in got] == [("a", 2), ("b", 3)]


async def test_a_frozen_system_gets_its_traffic_in_one_burst_on_thaw() -> None:
    def body(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.freeze("b")
        for n in range(3):
            ports["a"].send(_env("a", "b", n))
            ports["b"].send(_env("b", "a", 10 + n))
        net.clock.call_later(2.0, net.thaw, "b")

    got = await _with_net(1, ["a", "b"], body)
    assert [(who, n) for _, who, n in got] == [
        ("b", 0),
        ("a", 10),
        ("b", 1),
        ("a", 11),
        ("b", 2),
        ("a", 12),
    ]
    assert {t for t, _, _ in got} == {2.0}


async def test_a_crashed_system_neither_sends_nor_receives_until_it_comes_back() -> None:
    def body(net: FaultyNetwork, ports: dict[str, FaultyTransport]) -> None:
        net.crash("b")
        ports["a"].send(_env("a", "b", 1))
        ports["b"].send(_env("b", "a", 2))

    assert await _with_net(1, ["a", "b"], body) == []


def test_names_are_checked() -> None:
    async def main() -> None:
        net = FaultyNetwork(ManualClock(), random.Random(0), protocol_registry())
        with pytest.raises(ValueError, match="reserved"):
            net.transport(BROADCAST)

    anyio.run(main)
