"""Bounds on what a member may make this robot do in its own name (sans-IO, explicit time).

A member's messages are authenticated, but a member is still only trusted as far as the
protocol needs:

- :class:`BidBook`: an award is taken only for an auction this robot bid in (or a
  consensus task it claimed), from that auction's auctioneer, once. An award nobody
  asked for would otherwise tie the robot up for as long as its lease says.
- :class:`Budgets`: a token bucket per peer for the messages that make this robot work
  (a call for bids to price, news that re-evaluates running work): a member that sends
  them faster is refused the excess, the others are not slowed down.

Both tables are bounded: the oldest entries go first.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award

__all__ = ["BidBook", "Budgets", "bid_memory_s"]


def bid_memory_s(auction_window_s: float, award_timeout_s: float) -> float:
    """How long a bid is remembered: its auction's window and award, ten times over (an
    auction that closed may wait its turn behind others of its batch before it awards)."""
    return 10.0 * (auction_window_s + award_timeout_s)


class BidBook:
    """The bids this robot made and the consensus tasks it claimed, each kept for
    ``ttl_s`` clock seconds, at most ``max_entries`` of each (oldest forgotten first)."""

    def __init__(self, ttl_s: float, *, max_entries: int = 4096) -> None:
        self.ttl_s = ttl_s
        self.max_entries = max_entries
        #: auction -> (interface bid for, until when)
        self._bids: OrderedDict[AuctionId, tuple[str, float]] = OrderedDict()
        #: execution -> until when
        self._claims: OrderedDict[ExecutionId, float] = OrderedDict()

    def __len__(self) -> int:
        return len(self._bids) + len(self._claims)

    def bid(self, auction: AuctionId, interface: str, now: float) -> None:
        """This robot bid in ``auction`` for ``interface``."""
        self._bids.pop(auction, None)
        self._bids[auction] = (interface, now + self.ttl_s)
        self._trim(now)

    def claimed(self, execution: ExecutionId, now: float) -> None:
        """This robot claimed ``execution`` in a consensus round (its origin awards it)."""
        self._claims.pop(execution, None)
        self._claims[execution] = now + self.ttl_s
        self._trim(now)

    def refuse(self, sender: str, award: Award, now: float) -> str | None:
        """Why ``award`` (from ``sender``) is none this robot asked for, or None."""
        auction, execution = award.auction, award.execution
        if sender != auction.auctioneer:
            return f"award of {execution} from {sender}: only auctioneer {auction.auctioneer}"
        bid = self._bids.get(auction)
        if bid is not None and bid[1] >= now:
            if bid[0] != award.interface:
                return f"award of {execution}: we bid for {bid[0]}, not {award.interface}"
            return None
        until = self._claims.get(execution)
        if until is not None and until >= now and execution.origin == sender:
            return None
        return f"award of {execution}: we made no bid in auction {auction}"

    def taken(self, award: Award) -> None:
        """``award`` was taken: an auction (or claim) is awarded to one robot only once."""
        self._bids.pop(award.auction, None)
        self._claims.pop(award.execution, None)

    def _trim(self, now: float) -> None:
        # Entries expire in the order they were made (the ttl is the same for all).
        bids, claims = self._bids, self._claims
        while bids and (len(bids) > self.max_entries or next(iter(bids.values()))[1] < now):
            bids.popitem(last=False)
        while claims and (len(claims) > self.max_entries or next(iter(claims.values())) < now):
            claims.popitem(last=False)


@dataclass(slots=True)
class _Bucket:
    tokens: float
    at: float


class Budgets:
    """A token bucket per peer: ``burst`` messages at once, then ``rate`` per clock
    second. At most ``max_peers`` buckets are kept; the one used least recently goes
    (a forgotten peer starts with a full bucket: the bound is on memory, and a flood of
    made-up names costs each name its burst only)."""

    def __init__(self, rate: float, burst: float, *, max_peers: int = 1024) -> None:
        if not (rate > 0 and math.isfinite(rate)) or not burst >= 1:
            raise ValueError(f"budget: rate {rate!r} and burst {burst!r}, expected > 0 and >= 1")
        self.rate = rate
        self.burst = burst
        self.max_peers = max_peers
        self.refused = 0  #: messages over budget
        self._buckets: OrderedDict[str, _Bucket] = OrderedDict()

    def __len__(self) -> int:
        return len(self._buckets)

    def allow(self, peer: str, now: float, cost: float = 1.0) -> bool:
        """Whether ``peer`` may have ``cost`` more of this robot's work now (spent if so)."""
        buckets = self._buckets
        b = buckets.get(peer)
        if b is None:
            b = buckets[peer] = _Bucket(self.burst, now)
            if len(buckets) > self.max_peers:
                buckets.popitem(last=False)
        else:
            buckets.move_to_end(peer)
            # refilled for the time since it was last used (a clock going back adds nothing)
            tokens = b.tokens
            if now > b.at:
                tokens += (now - b.at) * self.rate
                b.at = now
            b.tokens = tokens if tokens < self.burst else self.burst
        if b.tokens >= cost:
            b.tokens -= cost
            return True
        self.refused += 1
        return False

    def forget(self, peer: str) -> None:
        self._buckets.pop(peer, None)
