"""The failure detector's settings and the timeouts that scale with the team by themselves
(Lifeguard's suspicion timeouts, SWIM's retransmissions, the detection bound): see
:mod:`~btcap.team.core.swim` and docs/membership.md."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ALPHA", "BETA", "CONFIRMATIONS", "MAX_HEALTH", "MAX_RELAYS", "RETRANSMIT", "SwimParams"]

ALPHA = 4.0  #: suspicion timeout, in periods per decade of team size (Lifeguard's alpha)
BETA = 6.0  #: the longest suspicion timeout, in shortest ones (Lifeguard's beta)
CONFIRMATIONS = 3  #: independent confirmations that bring a suspicion to its shortest
RETRANSMIT = 4  #: each news item is passed on RETRANSMIT·⌈log10(team + 1)⌉ times (lambda)
MAX_HEALTH = 8  #: the local health multiplier's ceiling (Lifeguard's awareness)
MAX_RELAYS = 64  #: indirect probes run for others at once (a flood of requests is dropped)


@dataclass(frozen=True, slots=True)
class SwimParams:
    """The protocol's settings; everything else scales with the team by itself."""

    period_s: float  #: a probe per period (the ``heartbeat_s`` setting)
    floor_s: float  #: the shortest suspicion timeout (the ``failure_timeout_s`` setting)
    news: int = 8  #: news items per message (the ``heartbeat_fanout`` setting)
    indirect: int = 3  #: members asked to probe an unanswering one (SWIM's k)
    max_members: int = 1024

    def __post_init__(self) -> None:
        if not self.floor_s > self.period_s:
            raise ValueError("failure_timeout_s: must exceed heartbeat_s")

    @property
    def probe_timeout_s(self) -> float:
        """How long a direct probe waits before asking others (half a period)."""
        return self.period_s / 2

    def suspicion_bounds(self, team: int) -> tuple[float, float]:
        """The shortest and longest suspicion timeouts in a team of ``team`` robots:
        ``alpha·log10(team)`` periods and beta times that, neither below the floor (a floor
        the user set is what they get where it is longer than the scaled timeouts)."""
        scaled = ALPHA * math.log10(max(team, 1)) * self.period_s
        lo = max(self.floor_s, scaled)
        return lo, max(lo, BETA * scaled)

    def suspicion_s(self, team: int, confirmations: int) -> float:
        """Lifeguard's timeout: the longest with no independent confirmation, down to the
        shortest with :data:`CONFIRMATIONS` of them (logarithmically)."""
        lo, hi = self.suspicion_bounds(team)
        k = min(CONFIRMATIONS, team - 2)
        if k < 1:
            return lo
        done = math.log(min(confirmations, k) + 1) / math.log(k + 1)
        return max(lo, hi - (hi - lo) * done)

    def retransmits(self, team: int) -> int:
        """How many times each news item is passed on."""
        return RETRANSMIT * max(1, math.ceil(math.log10(team + 1)))

    def hearsay_window_s(self, team: int) -> float:
        """A refutation passed on by others counts only this long after our last direct
        word from the robot: the longest suspicion plus two periods."""
        return self.suspicion_bounds(team)[1] + 2 * self.period_s

    def forget_s(self, team: int) -> float:
        """A member that never answered us is forgotten once silent this long: the
        longest suspicion (:mod:`~btcap.team.core.newcomers`)."""
        return self.suspicion_bounds(team)[1]

    def detection_bound_s(self, team: int) -> float:
        """The stated bound on detecting a dead robot once someone probed it: the probe's
        period, the suspicion's spread (every news item is sent ``retransmits`` times, one
        a period at least) and the longest suspicion timeout. O(log team)."""
        return self.period_s * (2 + self.retransmits(team)) + self.suspicion_bounds(team)[1]
