"""What each role may send: the one table, checked by the transport before delivery.

With keys a member's role is in its certificate (``btcap keys new NAME --role ROLE``);
an observer (``NAME+TAG``, e.g. ``btcap team status``) is an observer whatever its key.
Everything a role may not send is dropped before any actor sees it, counted under
``not allowed for its role`` in the transport's stats and logged at a falling rate.
Without keys nobody's role is authenticated: everyone may send everything, except an
observer, which declares itself by its id.

=========  ===================================================================
role       may send
=========  ===================================================================
robot      everything (it bids, runs and reports work, and may run missions)
operator   membership (heartbeats, goodbyes, rosters), its repository, queries,
           and what an origin sends: calls for bids, awards, inputs, keep-alives,
           pause and cancel, consensus offers, claims and prices, declining (``NoBid``)
observer   queries only: :class:`StatusQuery`, :class:`ActivityQuery`,
           :class:`DeparturesQuery`
=========  ===================================================================

Replies are not checked here: an answer reaches only the system that asked.
"""

from __future__ import annotations

from btcap.team.messages import (
    ActivityQuery,
    Award,
    CallForBids,
    CancelExecution,
    ConsensusClaim,
    ConsensusPrices,
    ConsensusTasks,
    DeparturesQuery,
    ExecutionInputs,
    Goodbye,
    Heartbeat,
    KeepAlive,
    NoBid,
    PauseExecution,
    ProbeRequest,
    RepositoryQuery,
    RepositoryState,
    Roster,
    RosterRequest,
    StatusQuery,
    Vouch,
)
from btcap.transports.identity import OBSERVER, OPERATOR, ROBOT
from btcap.transports.message import Message

__all__ = ["OBSERVER_SENDS", "OPERATOR_SENDS", "role_table"]

OBSERVER_SENDS: frozenset[type[Message]] = frozenset({StatusQuery, ActivityQuery, DeparturesQuery})
"""An observer only asks."""

OPERATOR_SENDS: frozenset[type[Message]] = OBSERVER_SENDS | {
    # a member of the team
    Heartbeat,
    Goodbye,
    Roster,
    RosterRequest,
    ProbeRequest,
    Vouch,
    RepositoryState,
    RepositoryQuery,
    # the origin of missions
    CallForBids,
    Award,
    ExecutionInputs,
    KeepAlive,
    PauseExecution,
    CancelExecution,
    ConsensusTasks,
    ConsensusClaim,
    ConsensusPrices,
    # it implements nothing: when asked to bid, it declines
    NoBid,
}
"""An operator runs missions; it never bids, executes or reports on a run."""


def role_table() -> dict[str, frozenset[type[Message]] | None]:
    """Role -> what it may send (None: anything), for :meth:`Transport.limit`. Message
    types beyond these (a plugin's, a node's) are for robots only."""
    return {ROBOT: None, OPERATOR: OPERATOR_SENDS, OBSERVER: OBSERVER_SENDS}
