"""A robot's answer to a call for bids: the cheapest implementation it may run now."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from btcap.team.messages import Bid, CallForBids, NoBid

__all__ = ["Bidder", "Evaluation", "bidding_after", "evaluate"]

_AFTER: ContextVar[bool] = ContextVar("btcap_bidding_after", default=False)


def bidding_after() -> bool:
    """Whether the bid being priced now is for after the work the robot holds (to queue
    the task, or a time-extended bid): an implementation's bid function prices it from
    where that work leaves the robot, not from where it is (see
    :mod:`btcap.team.core.body`)."""
    return _AFTER.get()


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
    """Bid ``wait`` (what the body must finish first; None: busy) plus the cheapest cost.

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
            cost = impl.cost(inputs)
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


def _why_no_cost(impl: Bidder) -> str:
    """Whose decision it was that ``impl`` cannot run the inputs, if it can tell (an
    :class:`~btcap.team.capabilities.implementation.Implementation` can)."""
    why = getattr(impl, "why_no_cost", None)
    return str(why()) if callable(why) else "cannot execute (its cost is None)"
