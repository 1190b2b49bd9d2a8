"""What a node needs from the tree that owns it: the node module builds on this, the
tree module on the node module, so neither needs the other's names."""

from __future__ import annotations

from collections.abc import Coroutine
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import asyncio

    from btcap.actors import ActorSystem, TimeSource

__all__ = ["TreeHost", "wake"]


class TreeHost(Protocol):
    """What a node needs from the tree that owns it; :class:`~btcap.bt.tree.Tree` is one.

    ``_adopt`` and ``_release`` take the node joining or leaving (a
    :class:`~btcap.bt.node.Node`); ``_told`` holds the paths of its nodes whose first
    error was told (:mod:`btcap.bt.told`).
    """

    _told: set[str]
    woken: bool

    @property
    def name(self) -> str: ...
    @property
    def clock(self) -> TimeSource: ...
    @property
    def system(self) -> ActorSystem | None: ...
    def start_task(
        self, coro: Coroutine[Any, Any, Any], *, name: str | None = None
    ) -> asyncio.Task[Any]: ...
    def nudge(self) -> None: ...
    def _adopt(self, node: Any) -> None: ...
    def _release(self, node: Any) -> None: ...


def wake(node: Any) -> None:
    """Ask the tree of ``node`` to tick again at once, as BehaviorTree.CPP's
    ``emitWakeUpSignal``: honoured by ``Tree.tick_once`` and ``Tree.run(wake=True)``."""
    tree = node._tree
    if tree is not None:
        tree.woken = True
