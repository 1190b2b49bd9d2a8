"""The halting invariant, checkable after any tick (for tests and debugging).

After a tick, a node may be active (RUNNING, ASSIGNED, UNASSIGNED) only if

1. it was ticked in that tick, and
2. its parent is active too: a node that gave a result, or was not ticked, has halted
   (unticked) everything below it in the same tick.

The one exception is below a node that holds a running child between the child's ticks
by design (``HOLDS_RUNNING_CHILD``: Throttle, and WhileDoElse while its condition runs):
the held subtree keeps its state.

Ticks are recorded with a profile hook on the nodes' ``tick`` functions, so the tick path
itself carries no bookkeeping for this.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from types import CodeType, FrameType
from typing import Any, TypeVar

from btcap.bt.node import Node
from btcap.bt.state import ACTIVE, State
from btcap.bt.tree import Subtree, Tree
from btcap.errors import BtcapError

__all__ = ["HaltingViolation", "check_halting", "record_ticks", "tick_checked"]

T = TypeVar("T")


class HaltingViolation(BtcapError, AssertionError):
    """A node was left active although nobody ticked it or its parent gave it up."""


def _family(node: Node, parent: Node | None = None) -> Iterator[tuple[Node, Node | None]]:
    """Every node with its parent, descending into the trees of Subtree nodes."""
    yield node, parent
    if isinstance(node, Subtree):
        yield from _family(node.inner.root, node)
    for c in node.children:
        yield from _family(c, node)


def record_ticks(tree: Tree, action: Callable[[], T]) -> tuple[T, list[Node]]:
    """Run ``action`` and return its result with the nodes of ``tree`` it ticked, in order."""
    nodes = {id(n): n for n, _ in _family(tree.root)}
    codes: set[CodeType] = {type(n).tick.__code__ for n in nodes.values()}
    ticked: list[Node] = []
    previous = sys.getprofile()

    def hook(frame: FrameType, event: str, arg: Any) -> None:
        if event == "call" and frame.f_code in codes:
            node = frame.f_locals.get("self")
            if node is not None and id(node) in nodes:
                ticked.append(node)

    sys.setprofile(hook)
    try:
        result = action()
    finally:
        sys.setprofile(previous)
    return result, ticked


def check_halting(tree: Tree, ticked: list[Node]) -> None:
    """Raise HaltingViolation unless the invariant holds after a tick that ticked ``ticked``."""
    was_ticked = {id(n) for n in ticked}
    held: set[int] = set()  # subtrees a holding decorator keeps without ticking them
    problems: list[str] = []
    for node, parent in _family(tree.root):
        if id(node) in held or (parent is not None and id(parent) in held):
            held.add(id(node))
            continue
        if getattr(node, "HOLDS_RUNNING_CHILD", False) and id(node) in was_ticked:
            held.update(id(c) for c in node.children if id(c) not in was_ticked)
        if node.state not in ACTIVE:
            continue
        if id(node) not in was_ticked:
            problems.append(f"{node.path} is {node.state.value} but was not ticked")
        elif parent is not None and parent.state not in ACTIVE:
            problems.append(
                f"{node.path} is {node.state.value} below {parent.path}, which is "
                f"{parent.state.value}: it should have been unticked"
            )
    if problems:
        raise HaltingViolation(f"tree {tree.name!r}: " + "; ".join(problems))


def tick_checked(tree: Tree) -> State:
    """``tree.tick()``, then :func:`check_halting`; returns the root's state."""
    state, ticked = record_ticks(tree, tree.tick)
    check_halting(tree, ticked)
    return state
