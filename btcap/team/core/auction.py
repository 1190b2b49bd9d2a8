"""The single-item auction as pure state (no I/O), so it can be tested without sockets.

An :class:`Auction` is opened for one capability execution with the set of robots
invited; it closes as soon as every invited robot that is still alive and not suspected
of failure has bid or declined, or when its window ends (a suspect is still invited: its
answer counts if it comes in time, but nobody waits for it). The ranking is by cost, then
robot id, so every auctioneer given the same bids picks the same winner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from btcap.team.ids import AuctionId
from btcap.team.messages import Bid, NoBid

__all__ = ["REASON_CHARS", "Auction", "AuctionOutcome", "bounded"]

#: How much of a reason a peer gives is kept (for the log and the user).
REASON_CHARS = 200


def bounded(reason: str) -> str:
    """A peer's words, cut to :data:`REASON_CHARS` (a peer must not fill our memory)."""
    return reason[:REASON_CHARS]


@dataclass(slots=True)
class AuctionOutcome:
    """What an auction produced: bids best first, and who declined or never answered."""

    ranking: list[Bid]
    declined: dict[str, str]
    silent: frozenset[str]

    def awardable(self, reserve: float | None = None) -> list[Bid]:
        """The bids to award in turn, cheapest first; with a reserve, only those below it
        (moving running work must pay off). Time-extended bids (``Bid.later``) are never
        awarded: they say what the task would cost later."""
        if reserve is None:
            return [b for b in self.ranking if not b.later]
        return [b for b in self.ranking if b.cost < reserve and not b.later]

    def later(self) -> list[Bid]:
        """The time-extended bids, cheapest first: what the task would cost each busy robot
        after the work it holds."""
        return [b for b in self.ranking if b.later]


@dataclass(slots=True)
class Auction:
    """One call for bids and the answers to it."""

    id: AuctionId
    interface: str
    invited: frozenset[str]
    deadline: float
    bids: dict[str, Bid] = field(default_factory=dict)
    declined: dict[str, str] = field(default_factory=dict)
    _pending: set[str] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._pending = set(self.invited)

    def offer(self, answer: Bid | NoBid, sender: str | None = None) -> bool:
        """Record a bid or decline; answers from robots not invited, late, twice, or
        sent by another robot than the one they speak for are ignored.

        Returns whether the answer was taken.
        """
        robot = answer.robot
        if answer.auction != self.id or robot not in self.invited:
            return False
        if (sender is not None and sender != robot) or robot in self.bids or robot in self.declined:
            return False
        self._pending.discard(robot)
        if isinstance(answer, Bid):
            if not math.isfinite(answer.cost) or answer.cost < 0:
                self.declined[robot] = f"invalid cost {answer.cost!r}"
            else:
                self.bids[robot] = answer
        else:
            self.declined[robot] = bounded(answer.reason)
        return True

    def member_lost(self, robot: str) -> None:
        """A robot left or failed: stop waiting for it."""
        self._pending.discard(robot)

    def excuse(self, robots: frozenset[str] | set[str]) -> None:
        """``robots`` are suspected of failure: stop waiting for them; an answer that
        still comes before the auction closes is taken as any other."""
        self._pending -= robots

    @property
    def waiting_for(self) -> frozenset[str]:
        return frozenset(self._pending)

    @property
    def answered_all(self) -> bool:
        return not self._pending

    def closed(self, now: float) -> bool:
        return not self._pending or now >= self.deadline

    def outcome(self) -> AuctionOutcome:
        ranking = sorted(self.bids.values(), key=lambda b: (b.cost, b.robot))
        return AuctionOutcome(ranking, dict(self.declined), self.waiting_for)
