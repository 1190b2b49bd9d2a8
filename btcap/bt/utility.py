"""Utility bounds: what executing a (sub)tree is expected to cost, for bidding."""

from __future__ import annotations

import math
from collections.abc import Sequence

import msgspec

__all__ = ["Utility", "fallback_utility", "parallel_utility", "sequence_utility"]


class Utility(msgspec.Struct, frozen=True, array_like=True):
    """Cost bounds of running a node to success and to failure; lower is better.

    ``can_execute`` false means the node cannot run at all here (a missing capability,
    a robot without the hardware); such a node is never bid with.
    """

    can_execute: bool = True
    success_lower: float = 0.0
    success_upper: float = 0.0
    failure_lower: float = 0.0
    failure_upper: float = 0.0

    def __add__(self, other: Utility) -> Utility:
        return Utility(
            self.can_execute and other.can_execute,
            self.success_lower + other.success_lower,
            self.success_upper + other.success_upper,
            self.failure_lower + other.failure_lower,
            self.failure_upper + other.failure_upper,
        )

    @property
    def expected_cost(self) -> float:
        """A single figure to compare bids by: the midpoint of the success bounds."""
        if not self.can_execute:
            return math.inf
        return (self.success_lower + self.success_upper) / 2.0


CANNOT = Utility(can_execute=False, success_lower=math.inf, success_upper=math.inf)


def sequence_utility(children: Sequence[Utility]) -> Utility:
    """Success needs every child; failure may come from any one of them."""
    if not children:
        return Utility()
    total = Utility()
    for c in children:
        total = total + c
    fail_lower = min(
        (sum(c.success_lower for c in children[:i]) + children[i].failure_lower)
        for i in range(len(children))
    )
    return Utility(
        total.can_execute,
        total.success_lower,
        total.success_upper,
        fail_lower,
        total.success_upper + max(c.failure_upper for c in children),
    )


def fallback_utility(children: Sequence[Utility]) -> Utility:
    """Success through the first child that succeeds after the ones before it failed."""
    usable = [c for c in children if c.can_execute]
    if not usable:
        return CANNOT
    s_lower = min(
        sum(p.failure_lower for p in usable[:i]) + c.success_lower for i, c in enumerate(usable)
    )
    s_upper = max(
        sum(p.failure_upper for p in usable[:i]) + c.success_upper for i, c in enumerate(usable)
    )
    f_total = sum(c.failure_lower for c in usable), sum(c.failure_upper for c in usable)
    return Utility(True, s_lower, s_upper, f_total[0], f_total[1])


def parallel_utility(children: Sequence[Utility]) -> Utility:
    """Children run together: their costs add up."""
    total = Utility()
    for c in children:
        total = total + c
    return total
