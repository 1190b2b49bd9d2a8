"""Shrinking a failing simulation plan: delta debugging (Zeller's ddmin) over its fault
events, then over the message fault rates, keeping each cut while the same invariant
still breaks. The result is a short schedule a person can read and replay."""

from __future__ import annotations

import math
from collections.abc import Callable

from btcap.sim.faults.plan import Fault, Plan
from btcap.sim.faults.run import Outcome, run_plan

__all__ = ["kind_of", "shrink"]


def kind_of(violation: str) -> str:
    """The invariant a violation line names ("12.250 double execution: ..." -> "double
    execution")."""
    head = violation.split(":", 1)[0]
    return head.split(" ", 1)[1] if " " in head else head


def shrink(
    outcome: Outcome,
    *,
    budget: int = 200,
    run: Callable[[Plan], Outcome] = run_plan,
) -> Outcome:
    """The smallest failing variant of ``outcome.plan`` found within ``budget`` runs that
    breaks the same invariant (``outcome`` itself if nothing smaller fails)."""
    if outcome.ok:
        return outcome
    want = kind_of(outcome.violations[0])
    best = outcome
    runs = 0

    def fails(faults: list[Fault]) -> bool:
        nonlocal best, runs
        runs += 1
        got = run(best.plan.with_faults(tuple(faults)))
        if any(kind_of(v) == want for v in got.violations):
            best = got
            return True
        return False

    faults = list(outcome.plan.faults)
    n = 2
    while faults and runs < budget:
        size = math.ceil(len(faults) / n)
        for i in range(0, len(faults), size):
            rest = faults[:i] + faults[i + size :]
            if runs < budget and fails(rest):
                faults = rest
                n = max(n - 1, 2)
                break
        else:
            if size == 1:
                break
            n = min(len(faults), 2 * n)
    for i, f in enumerate(list(faults)):  # then each message fault rate to zero
        if f.kind != "net":
            continue
        for k in range(3):
            if runs >= budget or f.rates[k] == 0.0:
                continue
            rates = tuple(0.0 if j == k else r for j, r in enumerate(f.rates))
            candidate = Fault(f.at, f.kind, f.robots, f.groups, rates)
            if fails([*faults[:i], candidate, *faults[i + 1 :]]):
                faults[i] = f = candidate
    return best
