"""The order in which a batch of closed auctions awards, and to whom (sans-IO).

An auctioneer holds the closed auctions of a batch (those that ran at the same time for
the same robots) until none still collecting bids competes for their robots; a
:class:`BatchPolicy` then says whether it plans the batch (a robot for each auction) and
which auction awards next. The four built-in policies are the strategies of
:mod:`btcap.team.core.planning`; a third-party strategy can bring its own (see
:class:`btcap.team.allocation.strategies.BatchStrategy`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence, Set
from typing import Protocol

from btcap.team.core.planning import optimal_plan, regret, sequential_plan
from btcap.team.messages import Bid

__all__ = ["ARRIVAL", "AUCTION", "OPTIMAL", "SEQUENTIAL", "BatchPolicy", "Planned"]

#: A robot for each task of the batch, in order (None: no robot for it).
Plan = Sequence[str | None]


class BatchPolicy(Protocol):
    """How a batch of closed auctions is awarded.

    ``batches`` False: each auction awards as it closes, oldest first, without waiting
    for competitors still open. ``plan`` is asked once per batch (when no auction of it
    has a plan yet) with each auction's awardable bids, cheapest first, and the robots
    already ``taken`` in the batch; it returns a robot per auction, or None to award
    without a plan. ``first`` gets each waiting auction's bids still free, its planned
    robot first, and returns the index of the one that awards next.
    """

    @property
    def batches(self) -> bool: ...

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None: ...

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int: ...


def _argmin(ordered: Sequence[Sequence[Bid]], key: Callable[[Sequence[Bid]], object]) -> int:
    """The index of the smallest key; ties: the lowest index (the oldest auction)."""
    return min(range(len(ordered)), key=lambda i: key(ordered[i]))  # type: ignore[arg-type,return-value]


def _best(bids: Sequence[Bid]) -> tuple[float, str]:
    """The bid an auction would award first (its planned robot's, if any)."""
    return (bids[0].cost, bids[0].robot) if bids else (math.inf, "")


class _ByRegret:
    """``auction``: no plan; the auction that would lose most by waiting goes first."""

    batches = True

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return None

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return _argmin(ordered, regret)


class Planned:
    """A planning policy: ``planner`` gives the batch's robots; the cheapest award first."""

    batches = True

    def __init__(self, planner: Callable[[Sequence[Sequence[Bid]], Set[str]], Plan]) -> None:
        self.planner = planner

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return self.planner(bids, taken)

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return _argmin(ordered, _best)


class _ByArrival:
    """``arrival``: each auction awards as it closes."""

    batches = False

    def plan(self, bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan | None:
        return None

    def first(self, ordered: Sequence[Sequence[Bid]]) -> int:
        return 0


AUCTION: BatchPolicy = _ByRegret()
SEQUENTIAL: BatchPolicy = Planned(sequential_plan)
OPTIMAL: BatchPolicy = Planned(optimal_plan)
ARRIVAL: BatchPolicy = _ByArrival()
