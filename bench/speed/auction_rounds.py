"""One measured auction round of :mod:`bench.speed.auction`: how rounds run back to back
within the bidders' budget of calls, or one at a time, and what each one records; the
teams they run in are :mod:`bench.speed.auction`'s."""

from __future__ import annotations

import asyncio
import gc
import itertools
import time
from collections.abc import Awaitable, Callable, Sequence
from typing import Any, NamedTuple

from btcap.actors import Address
from btcap.bench.cpumeter import CpuMeter
from btcap.team.allocation.auction import Assigned, AssignmentTask
from btcap.team.core.bounds import Budgets
from btcap.team.demo import ECHO
from btcap.team.ids import ExecutionId
from btcap.team.messages import CancelExecution
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.executor import CALLS_BURST, CALLS_PER_S
from btcap.team.runtime.mission import MissionControl

__all__ = ["BURST_ROUNDS", "Figures", "Plan", "Reference", "bidder_names", "call_budget", "rounds"]

BURST_ROUNDS = 100
"""Rounds back to back, at least, once the bidders' budget of calls has run dry: the bench
waits for it to refill this many."""
_INPUTS = {"value": 1, "stop": False}


class Plan(NamedTuple):
    warmup: int
    rounds: int
    quick: bool  # small teams: shorter waits for the joins to settle and for idle CPU


Figures = tuple[dict[str, Any], dict[str, Any], dict[str, Any]]
"""Per row: latency (ms), early closes, CPU per round (ms)."""
Reference = Callable[[str, int], Awaitable[None]]
"""Measured right before and after a row's rounds: ``reference(label, bidders)``."""


def call_budget() -> Budgets:
    """The bidders' budget of calls for bids from one auctioneer, mirrored: a bidder leaves
    calls over it unanswered (btcap.team.runtime.executor), so rounds started faster would
    measure the 5 s window. Rounds run back to back until the mirror says wait."""
    return Budgets(CALLS_PER_S, CALLS_BURST - 16)


async def room(budget: Budgets, cpu: CpuMeter | None, refill_s: float) -> None:
    """Take one call from the mirror of the bidders' budget; once it runs dry, wait
    (uncounted) ``refill_s`` for it to refill."""
    now = time.monotonic()
    if budget.allow("origin", now):
        return
    if cpu is not None:
        cpu.pause()
    # a token bucket refills with time; no event to wait for
    while not budget.allow("origin", now):
        await asyncio.sleep(refill_s)
        now, refill_s = time.monotonic(), 1 / CALLS_PER_S
    if cpu is not None:
        cpu.resume()


async def rounds(
    origin: Agent,
    bidders: Sequence[str],
    warmup: int,
    count: int,
    budget: Budgets,
    cpu: CpuMeter | None = None,
    gap_s: float = 0.0,
) -> tuple[list[float], int]:
    """Per-round latency in ms, and how many measured rounds closed early: in bursts of
    back-to-back rounds, or one every ``gap_s``."""
    auctioneer = origin.allocator
    system = origin.system
    candidates = frozenset(bidders)
    identity = ECHO.identity
    ids = itertools.count(1)
    lease_s = origin.config.lease_s
    samples: list[float] = []
    early = 0
    clock = time.perf_counter_ns
    for i in range(warmup + count):
        if gap_s > 0:
            await asyncio.sleep(gap_s)
        await room(budget, cpu, BURST_ROUNDS / CALLS_PER_S)
        execution = ExecutionId(origin.robot, f"bench/{len(bidders)}", next(ids))
        task = AssignmentTask(execution, ECHO.name, identity, _INPUTS, candidates, lease_s)
        closes = auctioneer.stats.early_closes
        if i == warmup:
            gc.collect()
        t0 = clock()
        won = await auctioneer.assign(task)
        t1 = clock()
        if not isinstance(won, Assigned):
            why = getattr(won, "reasons", won)
            raise RuntimeError(f"bench auction: round {i} with {len(bidders)} unassigned: {why}")
        # Free the winner: the cancel travels ahead of the next call for bids.
        system.tell(Address(won.robot, MissionControl.PATH), CancelExecution(execution, "bench"))
        if i >= warmup:
            samples.append((t1 - t0) / 1e6)
            early += auctioneer.stats.early_closes - closes
    return samples, early


def bidder_names(n: int) -> list[str]:
    return [f"b{i:02d}" for i in range(n)]
