"""The offline estimate of exchanges between busy robots."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from runwatch import watch_runs

from btcap.bench.allocation.exchanges import exchanged
from btcap.bench.allocation.optimum import Events, allocate
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


@pytest.mark.parametrize("strategy", ["auction", "optimal", "sequential"])
def test_two_busy_robots_driving_to_each_others_goals_swap(
    strategy: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # r00 takes task 0 (5 against 6); task 1 arrives while r00 is busy and r01 takes it at
    # 50, though r00 would do it for 4: only an exchange of the two busy robots mends it.
    cost = np.array([[5.0, 4.0], [6.0, 50.0]])
    twice = watch_runs(monkeypatch)
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
    twice = watch_runs(monkeypatch)
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


def test_a_chain_within_the_margin_is_not_made(monkeypatch: pytest.MonkeyPatch) -> None:
    cost = CHAIN.copy()
    cost[2, 2] = 40.0  # the chain: 54 against 47, within 0.2
    twice = watch_runs(monkeypatch)
    got = asyncio.run(
        asyncio.wait_for(allocate(cost, "auction", Events((0.0, 10.0, 20.0)), 30.0, 0), 30)
    )
    assert got.final == [1, 2, 0]
    assert twice == []
