"""A robot's answer to a call for bids: the cheapest implementation it may run now."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from btcap.team.messages import Bid, CallForBids, NoBid

__all__ = ["Bidder", "Evaluation", "bidding_after", "detour", "evaluate"]

_AFTER: ContextVar[bool] = ContextVar("btcap_bidding_after", default=False)
#: Set while a bid function runs: whether it asked :func:`bidding_after`.
_ASKED: ContextVar[list[bool] | None] = ContextVar("btcap_bidding_asked", default=None)


def bidding_after() -> bool:
    """Whether the bid being priced now is for after the work the robot holds (to queue
    the task, or a time-extended bid): an implementation's bid function prices it from
    where that work leaves the robot, not from where it is (see
    :mod:`btcap.team.core.body`).

    A bid function that never asks is taken to price from where the robot stands, and
    the framework prices the later work itself (see :func:`detour`)."""
    asked = _ASKED.get()
    if asked is not None:
        asked[0] = True
    return _AFTER.get()


def detour(cost: float, wait: float) -> float:
    """What a bid priced from where a busy robot stands (``cost``) may cost it after the
    work it holds, which costs ``wait`` to finish: that work may leave the robot as far
    away as it costs, and from there the way back is no dearer (costs are paths: the
    triangle inequality), so at most ``cost + wait``. An upper bound, not a guess: a plan
    never leaves a task waiting for a busy robot on a bid that was too low (a robot
    driving away from it), and a bid function that knows where the work leaves the
    robot (it asks :func:`bidding_after`) bids lower and closer to the truth."""
    return cost + wait


class Bidder(Protocol):
    """What bidding needs of an implementation (one is
    :class:`~btcap.team.capabilities.implementation.Implementation`)."""

    @property
    def name(self) -> str: ...

    def cost(self, inputs: Mapping[str, Any]) -> float | None: ...


B = TypeVar("B", bound=Bidder)


@dataclass(slots=True)
class Evaluation:
    """The answer, and the bid functions that raised (the shell logs them)."""

    answer: Bid | NoBid
    errors: list[tuple[str, Exception]] = field(default_factory=list)


def evaluate(
    cfb: CallForBids,
    robot: str,
    implementations: Sequence[B],
    inputs: Mapping[str, Any],
    *,
    wait: float | None,
    unmet: Callable[[B], str | None],
    later: bool = False,
) -> Evaluation:
    """Bid ``wait`` (what the body must finish first; None: busy) plus the cheapest cost
    (for after held work: see :func:`bidding_after`).

    ``unmet`` says why an implementation's preconditions do not hold. Ties go to the
    implementation whose name sorts first, so the same robot always bids the same way.
    ``later``: the robot cannot take the task now and bids what it would cost after
    ``wait`` (a time-extended bid, ``Bid.after``).
    """
    if not implementations:
        return Evaluation(NoBid(cfb.auction, robot, "no matching implementation"))
    if wait is None:
        return Evaluation(NoBid(cfb.auction, robot, "busy"))
    token = _AFTER.set(wait > 0)
    try:
        return _cheapest(cfb, robot, implementations, inputs, wait, unmet, later)
    finally:
        _AFTER.reset(token)


def _cheapest(
    cfb: CallForBids,
    robot: str,
    implementations: Sequence[B],
    inputs: Mapping[str, Any],
    wait: float,
    unmet: Callable[[B], str | None],
    later: bool,
) -> Evaluation:
    best: tuple[float, str] | None = None
    reasons: list[str] = []
    errors: list[tuple[str, Exception]] = []
    for impl in implementations:
        why = unmet(impl)
        if why is not None:
            reasons.append(why)
            continue
        try:
            cost = _priced(impl, inputs, wait)
        except Exception as exc:  # a user's bid function: it must not silence the robot
            errors.append((impl.name, exc))
            reasons.append(f"{impl.name}: its bid function raised {type(exc).__name__}")
            continue
        if cost is None:
            reasons.append(f"{impl.name}: {_why_no_cost(impl)}")
        elif best is None or (cost, impl.name) < best:
            best = (cost, impl.name)
    if best is None:
        return Evaluation(NoBid(cfb.auction, robot, "; ".join(reasons)), errors)
    return Evaluation(Bid(cfb.auction, robot, wait + best[0], best[1], wait, later), errors)


def _priced(impl: Bidder, inputs: Mapping[str, Any], wait: float) -> float | None:
    """``impl``'s cost for ``inputs``; for after ``wait`` of held work, with the
    :func:`detour` added unless its bid function asked :func:`bidding_after` (or it has
    none: a cost that is the tree's alone does not depend on where the robot is)."""
    if wait <= 0:
        return impl.cost(inputs)
    asked = [False]
    token = _ASKED.set(asked)
    try:
        cost = impl.cost(inputs)
    finally:
        _ASKED.reset(token)
    if cost is None or asked[0] or getattr(impl, "bid", True) is None:
        return cost
    return detour(cost, wait)


def _why_no_cost(impl: Bidder) -> str:
    """Whose decision it was that ``impl`` cannot run the inputs, if it can tell (an
    :class:`~btcap.team.capabilities.implementation.Implementation` can)."""
    why = getattr(impl, "why_no_cost", None)
    return str(why()) if callable(why) else "cannot execute (its cost is None)"
