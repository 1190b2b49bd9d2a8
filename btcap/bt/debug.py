"""Debug mode's check for restart loops: a node halted and started again, over and over.

The trap it catches: a reactive composite ticks its children from the first on every
tick, so an earlier child that finished is ticked again, and one that starts over when
ticked after finishing (a Repeat over a Wait, an Action) is running again, which halts
the child after it. That child is started again once the earlier one finishes, halted
again on the next tick, and never finishes: the tree runs for ever and nothing fails.

Debug mode is off by default and costs nothing then. It is on for a Tree made with
``debug=True``, or when the environment variable ``BTCAP_DEBUG`` is set (not to ``0``), or
in Python's development mode (``python -X dev``), as asyncio's debug mode is. It watches
state changes only (as an observer). A node halted because an earlier sibling started
over, in the tick the node started or the next, and started again, :data:`RESTARTS`
times in a row without finishing, gets one :class:`~btcap.bt.state.RestartLoopWarning`
naming it, the cause and the fix. A node that ran for longer before it was halted (a
patrol pre-empted by a recharge) is not in a loop, nor is one halted for another reason
(a condition that changed, a Parallel or a Timeout that decided); finishing, a reset or
shutdown forgets the count.
"""

from __future__ import annotations

import os
import sys
import warnings

from btcap.bt.composites import Fallback, ReactiveFallback, ReactiveSequence, Sequence
from btcap.bt.node import Node
from btcap.bt.state import RestartLoopWarning, State

__all__ = ["RESTARTS", "RestartMonitor", "debug_default"]

#: Halt-restarts in a row, each after at most a tick of running, that make a warning.
RESTARTS = 3

_PAUSED = State.PAUSED
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)
_DONE = (State.SUCCEEDED, State.FAILED, State.ERROR)

#: The composite that resumes at its running child, for each one that re-ticks from the first.
_RESUMING: dict[type[Node], type[Node]] = {
    ReactiveSequence: Sequence,
    ReactiveFallback: Fallback,
}


def debug_default() -> bool:
    """Whether a Tree made without ``debug=`` checks: ``BTCAP_DEBUG`` or ``python -X dev``."""
    return bool(sys.flags.dev_mode) or os.environ.get("BTCAP_DEBUG", "") not in ("", "0")


class _Track:
    """One node's activation: when it started, and its run of short halt-restarts."""

    __slots__ = ("cause", "cut_short", "started", "streak")

    def __init__(self, started: int) -> None:
        self.started = started
        self.streak = 0
        self.cut_short = False  # halted at most a tick after it started
        self.cause: Node | None = None  # the earlier sibling that started over, if seen


class RestartMonitor:
    """The observer debug mode adds to a Tree (and shares with its subtrees).

    The tree counts its ticks in ``ticks`` and calls :meth:`flush` after each, so the
    warnings are raised outside any node's tick (an error filter then fails the caller,
    not a node) and only the topmost node of a subtree that loops is named.
    """

    __slots__ = ("_last_restart", "_pending", "_restart_tick", "_track", "_warned", "ticks")

    def __init__(self) -> None:
        self.ticks = 0
        self._track: dict[Node, _Track] = {}
        self._warned: set[Node] = set()
        self._pending: list[Node] = []
        self._last_restart: Node | None = None  # the last node started again after finishing
        self._restart_tick = -1  # and in which tick

    def __call__(self, node: Node, old: State, new: State) -> None:
        if new in _ACTIVE:
            if old in _ACTIVE:
                return  # running -> assigned: the same activation
            track = self._track.get(node)
            if track is None:
                track = self._track[node] = _Track(self.ticks)
            elif old is _PAUSED and track.cut_short:
                track.streak += 1
                if track.streak >= RESTARTS and node not in self._warned:
                    self._pending.append(node)
            elif old is _PAUSED:
                track.streak = 0
            track.started = self.ticks
            track.cut_short = False
            if old in _DONE:  # its descendants come first: this ends at the topmost
                self._last_restart, self._restart_tick = node, self.ticks
        elif new is _PAUSED:
            track = self._track.get(node)
            if track is None:
                track = self._track[node] = _Track(self.ticks)
            if old in _ACTIVE:
                track.cause = cause = self._earlier_sibling_restarted(node)
                track.cut_short = cause is not None and self.ticks - track.started <= 1
                if not track.cut_short:
                    track.streak = 0
        else:  # finished, reset, shut down: whatever loop there was ended
            self._track.pop(node, None)

    def _earlier_sibling_restarted(self, node: Node) -> Node | None:
        """The sibling before ``node`` that started over in this tick, if the last node to
        start over after finishing was one: what halts a node in a restart loop."""
        cause, parent = self._last_restart, node.parent_node
        if cause is None or self._restart_tick != self.ticks or parent is None:
            return None
        if cause.parent_node is not parent:
            return None
        kids = parent.children
        return cause if kids.index(cause) < kids.index(node) else None

    @property
    def pending(self) -> bool:
        return bool(self._pending)

    def flush(self, stacklevel: int = 3) -> None:
        """Warn once for each node that tripped, unless a node above it is named."""
        pending, self._pending = self._pending, []
        pending.sort(key=lambda n: n.path.count("/"))
        tripped = set(pending)
        for node in pending:
            if node in self._warned:
                continue
            above = _ancestors(node)
            self._warned.add(node)
            if any(a in self._warned or a in tripped for a in above):
                continue
            warnings.warn(self._message(node), RestartLoopWarning, stacklevel=stacklevel)

    def _message(self, node: Node) -> str:
        track = self._track.get(node)
        cause = track.cause if track is not None else None
        parent = node.parent_node
        assert parent is not None  # a sibling halted it
        assert cause is not None
        fix = next((_RESUMING[c] for c in type(parent).__mro__ if c in _RESUMING), None)
        use = f"use {fix.__name__}, which" if fix is not None else "use a composite that"
        return (
            f"node {node.path!r} ({type(node).__name__}) was halted and started again "
            f"{RESTARTS} times in a row without finishing: its parent {parent.path!r} "
            f"({type(parent).__name__}) ticks the earlier child {cause.path!r} again, which "
            f"starts over after finishing and halts this one; {use} resumes at the running "
            f"child, or make {cause.path!r} keep its result (e.g. wrap it in RunOnce)"
        )


def _ancestors(node: Node) -> list[Node]:
    out: list[Node] = []
    p = node.parent_node
    while p is not None:
        out.append(p)
        p = p.parent_node
    return out
