"""Settings and counters of a robot's mission control."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MissionConfig", "MissionStats"]


@dataclass(slots=True, kw_only=True)
class MissionConfig:
    """Protocol timing in clock seconds, and the allocation policies."""

    #: How long an execution lives without word from the other side. The origin grants
    #: it with every award; the executor gives the run up after ``0.8 * lease_s``.
    lease_s: float = 1.0
    #: How often the origin renews a running execution's lease (below ``lease_s``).
    keepalive_s: float = 0.2
    #: An auction closes after this long, or earlier once every live, eligible member
    #: has bid or declined.
    auction_window_s: float = 1.0
    #: How long an auctioneer waits for the winner to accept an award before the next
    #: bidder gets it.
    award_timeout_s: float = 0.5
    #: Running work is re-evaluated every ``reevaluate_s`` clock seconds and whenever the
    #: team changes (a robot joins, comes free or changes): it moves to another robot only
    #: if that one bids at least ``move_margin`` below what the current executor now bids
    #: to finish it (0.2: a fifth cheaper), which covers the cost of switching and keeps
    #: two near-equal robots from passing work back and forth. None: never moved.
    reevaluate_s: float | None = 30.0
    move_margin: float = 0.2
    #: How auctions competing for the same robots are awarded: ``auction`` (each to its
    #: cheapest free bidder, by regret), ``sequential`` (a greedy plan improved by
    #: exchanges), ``optimal`` (least total cost) or ``arrival`` (each as it closes); see
    #: :mod:`btcap.team.core.planning`.
    strategy: str = "auction"
    #: Older name of ``move_margin`` for the join case; when set, it is the margin.
    rebid_on_join: float | None = None
    #: A busy robot also bids for one more execution, to start when its current work
    #: ends, at its current bid plus the new one. Off: a busy robot declines to bid.
    queue_after_current: bool = False


@dataclass(slots=True)
class MissionStats:
    requests: int = 0
    assigned: int = 0
    unassigned: int = 0
    lost: int = 0
    hosted: int = 0
    declined: int = 0
    moved: int = 0
    refused: int = 0  #: messages a peer had no right to send, or that made no sense
    errors: int = 0  #: failures of this robot's own code (bid functions, builds), logged
