"""How closed auctions competing for the same robots are awarded: the order and, for the
optimal strategy, who gets what.

``auction`` (the default) awards the globally cheapest robot-task pair first, then the
next (sequential single-item auctions over the tasks pending together); ``optimal``
assigns the batch for the least total cost (the Hungarian method) and awards that plan;
``arrival`` awards each auction as it closes, to its cheapest bidder (btcap's first
behaviour, kept as a baseline).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from btcap.team.messages import Bid

__all__ = ["STRATEGIES", "check_strategy", "optimal_plan"]

STRATEGIES = ("auction", "optimal", "arrival")


def check_strategy(name: str) -> str:
    if name not in STRATEGIES:
        raise ValueError(f"allocation strategy {name!r}: expected one of {', '.join(STRATEGIES)}")
    return name


def optimal_plan(bids: Sequence[Sequence[Bid]], taken: set[str]) -> list[str | None]:
    """For each task (its awardable bids), the robot that gets it in an assignment of least
    total cost, each robot at most once and never one already ``taken``; None for a task
    that gets no robot."""
    robots = sorted({b.robot for task in bids for b in task} - taken)
    if not robots or not bids:
        return [None] * len(bids)
    index = {r: i for i, r in enumerate(robots)}
    big = 1.0 + sum(b.cost for task in bids for b in task if math.isfinite(b.cost))
    cost = np.full((len(bids), len(robots)), big * 2)
    for t, task in enumerate(bids):
        for b in task:
            if b.robot in index:
                cost[t, index[b.robot]] = min(cost[t, index[b.robot]], b.cost)
    rows, cols = linear_sum_assignment(cost)
    plan: list[str | None] = [None] * len(bids)
    for t, r in zip(rows, cols, strict=True):
        if cost[t, r] < big * 2:  # a real bid, not the stand-in for none
            plan[t] = robots[r]
    return plan
