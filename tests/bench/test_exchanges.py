"""The offline estimate of exchanges between busy robots."""

from __future__ import annotations

import numpy as np

from btcap.bench.exchanges import exchanged


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
