"""How BehaviorTree.CPP-named composites go on after a child that gave SKIPPED.

BehaviorTree.CPP 4.8 (``src/controls/*.cpp``) passes a skipped child over as if it were
absent, and a composite whose children all skipped in one run is SKIPPED itself. The
composites' own loops stay as they were: at the first SKIPPED they hand the rest of the
tick to a function here, so trees that never skip pay nothing for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from btcap.bt.host import wake
from btcap.bt.node import Node
from btcap.bt.state import State

__all__ = ["forget_skipped", "memory_rest", "reactive_rest"]

_RUNNING, _SUCCEEDED, _FAILED = State.RUNNING, State.SUCCEEDED, State.FAILED
_ERROR, _IDLE, _SKIPPED = State.ERROR, State.IDLE, State.SKIPPED
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


def _passes(s: State, passing: State) -> bool:
    """Whether ``s`` lets the composite go on (ERROR counts as FAILED)."""
    return s is passing or (passing is _FAILED and s is _ERROR)


def _all_skipped(children: Sequence[Node]) -> bool:
    return all(c.state is _SKIPPED for c in children)


def reactive_rest(node: Any, first: Node, passing: State) -> State:
    """The rest of a reactive tick (ReactiveSequence, ReactiveFallback) from ``first``, a
    child that gave SKIPPED: a child giving ``passing`` goes on, anything else ends the
    tick as the plain loop does. SKIPPED if every child skipped, else ``passing``."""
    children = node.children
    k = children.index(first)  # identity: nodes do not define __eq__
    only_skips = k == 0
    for i in range(k + 1, len(children)):
        s = children[i].tick()
        if s is _SKIPPED:
            continue
        only_skips = False
        if _passes(s, passing):
            continue
        if node._high > i:
            node._halt_after(i)
        else:
            node._high = i
        if s is _SUCCEEDED or s is _FAILED:
            return s
        return _FAILED if s is _ERROR else _RUNNING
    node._high = len(children) - 1
    return _SKIPPED if only_skips else passing


def memory_rest(node: Any, i: int, passing: State) -> State:
    """The rest of a run of a Sequence or Fallback (and their Async and WithMemory kinds)
    from child ``i``, which gave SKIPPED. The children before ``i`` gave ``passing`` or
    SKIPPED in this run, and their states still say which (nothing resets them before
    the run ends; a memory sequence's failure forgets its skipped ones). With
    ``_YIELDS`` (AsyncSequence, AsyncFallback) a child that gave ``passing`` at once ends
    the tick, as in their plain loop."""
    children = node.children
    n = len(children)
    i += 1
    while i < n:
        child = children[i]
        instant = child.state not in _ACTIVE
        s = child.tick()
        if _passes(s, passing):
            i += 1
            if node._YIELDS and instant and i < n:
                node._current = i
                wake(node)
                return _RUNNING
        elif s is _SKIPPED:
            i += 1
        elif s is _SUCCEEDED or s is _FAILED or s is _ERROR:
            if node._RESUME_FAILED and passing is _SUCCEEDED:
                node._failed_at(i)
            else:
                node._current = 0
            return _FAILED if s is _ERROR else s
        else:
            node._current = i
            return _RUNNING
    node._current = 0
    return _SKIPPED if _all_skipped(children) else passing


def forget_skipped(children: Sequence[Node], i: int) -> None:
    """A memory sequence failed at child ``i``: the children it skipped before belong to
    no later run, and are IDLE again (BehaviorTree.CPP keeps a skipped node's status)."""
    for c in children[:i]:
        if c.state is _SKIPPED:
            c._set(_IDLE)
