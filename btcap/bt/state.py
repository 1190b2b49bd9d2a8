"""Node states, the errors of the node life cycle and btcap's warnings."""

from __future__ import annotations

import enum

from btcap._enum import FastEnumType
from btcap.errors import BtcapError, BtcapWarning

__all__ = [
    "ACTIVE",
    "DONE",
    "ENDED",
    "FAILED",
    "RUNNING",
    "SKIPPED",
    "SUCCEEDED",
    "BtcapWarning",
    "IllegalTransition",
    "NodeErrorWarning",
    "RegistryError",
    "RestartLoopWarning",
    "State",
    "TreeError",
    "TreeTimeout",
    "UnassignableWarning",
]


class State(enum.Enum, metaclass=FastEnumType):
    """The state of a node after its last action.

    UNASSIGNED and ASSIGNED belong to capability nodes still waiting for (or just given)
    an executor; control flow treats them, like PAUSED, as RUNNING. SKIPPED is
    BehaviorTree.CPP's: a node whose ``_skipIf``/``_while`` said not to run it (or a
    ``RunOnce`` after its run) did nothing, and its BehaviorTree.CPP-named parent goes on as
    if it were absent; only those nodes give it, never a capability node or team code.
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
    SKIPPED = "skipped"


# A leaf's tick reads these as globals of its own module (``from btcap import
# SUCCEEDED``), which CPython specialises; ``State.SUCCEEDED`` is a class attribute read,
# which 3.11 does not (~24 ns a tick more). Same objects: ``SUCCEEDED is State.SUCCEEDED``.
SUCCEEDED = State.SUCCEEDED
FAILED = State.FAILED
RUNNING = State.RUNNING
SKIPPED = State.SKIPPED

#: States in which a node has work in progress (and must be unticked when abandoned).
ACTIVE = frozenset({State.RUNNING, State.ASSIGNED, State.UNASSIGNED})

#: States that end a tick with a result.
DONE = frozenset({State.SUCCEEDED, State.FAILED, State.ERROR})

#: States that end a run: a result, or a root that skipped itself (BehaviorTree.CPP's
#: ``tickWhileRunning`` returns SKIPPED then).
ENDED = DONE | {State.SKIPPED}


class TreeError(BtcapError):
    """A tree or tree file is invalid: the message names the node, port or field."""


class IllegalTransition(TreeError):
    """An action was asked of a node in a state that does not allow it."""


class RegistryError(TreeError):
    """A node type or type name is unknown, duplicated, or a node plugin is broken."""


class TreeTimeout(TreeError, TimeoutError):
    """:meth:`~btcap.bt.tree.Tree.run` reached its time or tick limit without a result.

    The tree has been halted (unticked: its background work is cancelled, its progress
    kept) when this is raised. ``limit`` is the limit reached (``"timeout_s"`` or
    ``"max_ticks"``) and ``value`` its value, ``running`` the paths of the nodes that were
    still running, ``state`` the root's last state and ``ticks`` the ticks of the run.
    """

    def __init__(
        self,
        tree: str,
        limit: str,
        value: float,
        *,
        running: tuple[str, ...],
        state: State,
        ticks: int,
    ) -> None:
        what = f"time limit of {value:g} s" if limit == "timeout_s" else f"limit of {value} ticks"
        super().__init__(
            f"tree {tree!r} reached its {what} after {ticks} tick{'' if ticks == 1 else 's'} "
            f"without a result and was halted; still running: {', '.join(running) or 'nothing'}"
        )
        self.limit = limit
        self.value = value
        self.running = running
        self.state = state
        self.ticks = ticks


class RestartLoopWarning(BtcapWarning):
    """A node keeps being halted and started again without ever finishing (debug mode)."""


class NodeErrorWarning(BtcapWarning):
    """A node's action raised: said once per node of a tree, pointing at the line that
    raised. ``warnings.filterwarnings("error", category=NodeErrorWarning)`` makes the
    first such error raise out of ``Tree.tick`` instead (tests, debugging)."""


class UnassignableWarning(BtcapWarning):
    """Nobody in the team can take a capability (each robot's reason given): said once per
    capability node while it waits, and when its ``assignment_timeout_s`` ends the wait."""
