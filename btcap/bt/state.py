"""Node states and the errors of the node life cycle."""

from __future__ import annotations

import enum

__all__ = ["ACTIVE", "DONE", "IllegalTransition", "State", "TreeError"]


class State(enum.Enum):
    """The state of a node after its last action.

    UNASSIGNED and ASSIGNED belong to capability nodes still waiting for (or just given)
    an executor; control flow treats them, like PAUSED, as RUNNING.
    """

    UNINITIALIZED = "uninitialized"
    IDLE = "idle"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    ERROR = "error"
    SHUTDOWN = "shutdown"
    PAUSED = "paused"
    UNASSIGNED = "unassigned"
    ASSIGNED = "assigned"


#: States in which a node has work in progress (and must be unticked when abandoned).
ACTIVE = frozenset({State.RUNNING, State.ASSIGNED, State.UNASSIGNED})

#: States that end a tick with a result.
DONE = frozenset({State.SUCCEEDED, State.FAILED, State.ERROR})


class TreeError(Exception):
    """A tree or tree file is invalid: the message names the node, port or field."""


class IllegalTransition(TreeError):
    """An action was asked of a node in a state that does not allow it."""
