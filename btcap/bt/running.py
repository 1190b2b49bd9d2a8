"""Ticking a tree at a rate on its clock until a result, or until a limit stops it."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from btcap.bt.node import Node
from btcap.bt.state import ACTIVE, DONE, State, TreeTimeout

if TYPE_CHECKING:
    from btcap.actors import TimeSource

__all__ = ["Runnable", "run_tree", "running_paths"]


class Runnable(Protocol):
    """What :func:`run_tree` needs of a tree; :class:`~btcap.bt.tree.Tree` is one."""

    name: str
    root: Node
    clock: TimeSource

    def tick(self) -> State: ...
    def untick(self) -> None: ...


async def run_tree(
    tree: Runnable,
    rate_hz: float,
    until: Callable[[State], bool] | None,
    max_ticks: int | None,
    timeout_s: float | None,
) -> State:
    """:meth:`Tree.run <btcap.bt.tree.Tree.run>`: tick drift-free at ``rate_hz`` until
    ``until(state)`` (default: a result); at a limit, untick and raise TreeTimeout."""
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    if max_ticks is not None and max_ticks < 1:
        raise ValueError(f"max_ticks must be >= 1 or None, got {max_ticks}")
    if timeout_s is not None and not timeout_s > 0:
        raise ValueError(f"timeout_s must be > 0 or None, got {timeout_s}")
    stop = until or (lambda s: s in DONE)
    clock = tree.clock
    period = 1.0 / rate_hz
    deadline = clock.now()
    end = None if timeout_s is None else deadline + timeout_s
    ticks = 0
    while True:
        state = tree.tick()
        ticks += 1
        if stop(state):
            return state
        if max_ticks is not None and ticks >= max_ticks:
            raise _halt(tree, "max_ticks", max_ticks, state, ticks)
        deadline += period
        now = clock.now()
        if deadline < now - period:  # fell far behind: skip, don't burst
            deadline = now
        if end is not None and timeout_s is not None and deadline > end:
            await clock.sleep_until(end)  # not a tick later: the limit is the limit
            raise _halt(tree, "timeout_s", timeout_s, state, ticks)
        await clock.sleep_until(deadline)


def _halt(tree: Runnable, limit: str, value: float, state: State, ticks: int) -> TreeTimeout:
    """Untick the tree at a limit; the error to raise, naming the work it was doing."""
    running = tuple(running_paths(tree.root))
    tree.untick()
    return TreeTimeout(tree.name, limit, value, running=running, state=state, ticks=ticks)


def running_paths(root: Node) -> list[str]:
    """Paths of the nodes doing the work of a running tree: active nodes without an
    active child (inside a Subtree, below the Subtree's path)."""
    out: list[str] = []

    def visit(node: Node, prefix: str) -> None:
        if node.state not in ACTIVE:
            return
        inner = getattr(node, "inner", None)  # a Subtree: its tree's nodes are its own
        below = inner.root.children if inner is not None else node.children
        busy = [c for c in below if c.state in ACTIVE]
        if not busy:
            out.append(prefix + node.name)
        for c in busy:
            visit(c, f"{prefix}{node.name}/")

    visit(root, "")
    return out
