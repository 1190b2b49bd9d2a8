"""Running work whose own cost estimate rose: news for re-evaluation.

An executor re-estimates what finishing each run it holds would cost. Progress makes the
estimate fall, which is no news; a rise beyond ``margin`` (the path got blocked, the goal
moved) may mean another robot would now do it cheaper, so the run's origin re-evaluates
at once instead of at its next period. The estimate that rose becomes the new baseline,
so a steady rise is reported once per margin, not every time.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from btcap.team.ids import ExecutionId

__all__ = ["CostWatch"]


class CostWatch:
    """Baselines per running execution (at most ``limit``: the oldest go first)."""

    def __init__(self, margin: float, *, limit: int = 4096) -> None:
        if margin < 0:
            raise ValueError(f"cost margin {margin}: expected at least 0")
        self.margin = margin
        self.limit = limit
        self._base: dict[ExecutionId, float] = {}

    def see(self, execution: ExecutionId, cost: float) -> bool:
        """Note a fresh estimate; True if it rose beyond the margin over the baseline."""
        if math.isnan(cost):
            return False  # no estimate: as a baseline it would hide every later rise
        base = self._base.get(execution)
        if base is None:
            self._base[execution] = cost
            while len(self._base) > self.limit:
                del self._base[next(iter(self._base))]
            return False
        if cost > base * (1 + self.margin) and cost - base > 1e-9:
            self._base[execution] = cost
            return True
        self._base[execution] = min(base, cost)
        return False

    def keep_only(self, executions: Iterable[ExecutionId]) -> None:
        """Forget the runs that ended."""
        live = set(executions)
        for execution in [e for e in self._base if e not in live]:
            del self._base[execution]

    def __len__(self) -> int:
        return len(self._base)
