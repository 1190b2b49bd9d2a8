"""Counters of a robot's mission control (its settings are in :mod:`btcap.team.settings`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["MissionStats"]


@dataclass(slots=True)
class MissionStats:
    requests: int = 0
    assigned: int = 0
    unassigned: int = 0
    lost: int = 0
    hosted: int = 0
    declined: int = 0
    moved: int = 0
    exchanged: int = 0  #: exchanges of running work made (pairs and chains; see moving)
    exchange_tries_left_off: int = 0  #: re-evaluations that stopped at EXCHANGE_TRIES
    #: moves and exchanges that handed a task back to the robot it left within the
    #: hold-down (:mod:`btcap.team.core.handovers`): 0 while the hold-down is on
    undone: int = 0
    held_back: int = 0  #: hand-overs the hold-down refused (a robot or a cycle left out)
    foreseen_back: int = 0  #: exchanges not made: a leg would come back (``comes_back``)
    refused: int = 0  #: messages a peer had no right to send, or that made no sense
    errors: int = 0  #: failures of this robot's own code (bid functions, builds), logged
    news_ignored: int = 0  #: teammates' news over their budget (see Reevaluation.budget)
    #: runs an award built on the event loop, with no spare built ahead in a worker
    #: thread (two awards faster than a spare, or a build that fails in a thread)
    built_on_loop: int = 0
