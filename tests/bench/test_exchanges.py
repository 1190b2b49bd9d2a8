"""The offline estimate of exchanges between busy robots."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from btcap.bench.allocation import Events, allocate
from btcap.bench.exchanges import exchanged
from btcap.team.core.hosting import HostLeases
from btcap.team.ids import ExecutionId
from btcap.team.runtime import moving


def test_crossed_robots_are_exchanged_until_nothing_pays() -> None:
    # robot r is next to task r; the allocation has them crossed (a swap and a 3-chain)
    cost = np.full((5, 5), 20.0)
    np.fill_diagonal(cost, 1.0)
    final = [1, 0, 3, 4, 2]
    for t, r in enumerate(final):
        cost[r, t] = 5.0
    assert exchanged(cost, final, 0.2, 3) == [0, 1, 2, 3, 4]
    assert exchanged(cost, final, 0.2, 2) == [0, 1, 3, 4, 2]  # no swap undoes the chain
    assert exchanged(cost, [0, 1, -1, -1, -1], 0.0, 3) == [0, 1, -1, -1, -1]


def _watch_runs(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Every moment two robots run the same task (its node) with inputs, unpaused, as a
    list (a replacement holds its robot paused until its node adopts it)."""
    hosts: list[HostLeases[Any]] = []
    twice: list[str] = []
    init, inputs, release = HostLeases.__init__, HostLeases.inputs, HostLeases.release

    def check() -> None:
        nodes = [
            e.node
            for h in hosts
            for e, run in h.hosted.items()
            if h.body.running == e and not run.paused
        ]
        twice.extend(n for n in set(nodes) if nodes.count(n) > 1)

    def init_(self: HostLeases[Any], *args: Any, **kwargs: Any) -> None:
        init(self, *args, **kwargs)
        hosts.append(self)

    def inputs_(self: HostLeases[Any], *args: Any, **kwargs: Any) -> Any:
        out = inputs(self, *args, **kwargs)
        check()
        return out

    def release_(self: HostLeases[Any], execution: ExecutionId) -> Any:
        out = release(self, execution)
        check()
        return out

    monkeypatch.setattr(HostLeases, "__init__", init_)
    monkeypatch.setattr(HostLeases, "inputs", inputs_)
    monkeypatch.setattr(HostLeases, "release", release_)
    return twice


@pytest.mark.parametrize("strategy", ["auction", "optimal", "sequential"])
def test_two_busy_robots_driving_to_each_others_goals_swap(
    strategy: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # r00 takes task 0 (5 against 6); task 1 arrives while r00 is busy and r01 takes it at
    # 50, though r00 would do it for 4: only an exchange of the two busy robots mends it.
    cost = np.array([[5.0, 4.0], [6.0, 50.0]])
    twice = _watch_runs(monkeypatch)
    got = asyncio.run(asyncio.wait_for(allocate(cost, strategy, Events((0.0, 10.0)), 30.0, 0), 30))
    assert got.final == [1, 0]
    assert twice == []
    fixed = asyncio.run(
        asyncio.wait_for(allocate(cost, strategy, Events((0.0, 10.0)), None, 0), 30)
    )
    assert fixed.final == [0, 1]  # without re-evaluation it stays crossed


def test_a_swap_within_the_margin_is_not_made() -> None:
    cost = np.array([[5.0, 45.0], [6.0, 50.0]])  # 55 against 51: within 0.2
    got = asyncio.run(asyncio.wait_for(allocate(cost, "auction", Events((0.0, 10.0)), 30.0, 0), 30))
    assert got.final == [0, 1]


CHAIN = np.array([[5.0, 50.0, 40.0], [4.0, 2.0, 50.0], [50.0, 10.0, 1.0]])


@pytest.mark.parametrize("strategy", ["auction", "optimal", "sequential"])
def test_three_busy_robots_in_a_crossed_chain_exchange_all_three(
    strategy: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Arrivals leave task 0 on r01, task 1 on r02, task 2 on r00 (54); each robot is next
    # to the task it does not run (8 in all), and no swap of two of them pays.
    twice = _watch_runs(monkeypatch)
    got = asyncio.run(
        asyncio.wait_for(allocate(CHAIN, strategy, Events((0.0, 10.0, 20.0)), 30.0, 0), 30)
    )
    assert got.final == [0, 1, 2]
    assert twice == []


def test_without_chains_the_crossed_three_stay_crossed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(moving, "EXCHANGE_CHAIN", 2)
    got = asyncio.run(
        asyncio.wait_for(allocate(CHAIN, "auction", Events((0.0, 10.0, 20.0)), 30.0, 0), 30)
    )
    assert got.final == [1, 2, 0]
