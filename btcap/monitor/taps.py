"""Where a monitor's events come from: tree observers and a robot's team hooks.

A tree tap costs the ticking tree one dictionary store per state change (the latest
state per node, turned into an event when the monitor flushes) plus a set lookup; only
capability nodes, whose transitions are rare and make the timeline, are reported at
once with their clock time.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from btcap.bt.node import Node
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.monitor.view import Event
from btcap.team.capability import Capability

__all__ = ["Emit", "TreeTap"]

#: Hands one event to the monitor (which stamps nothing: events carry their own time).
Emit = Callable[[Event], None]

_UNASSIGNED = State.UNASSIGNED


class TreeTap:
    """Observes one tree of one robot: states batched, capability runs at once."""

    def __init__(
        self, tree: Tree, robot: str, name: str, emit: Emit, ended: Callable[[str, str], str | None]
    ) -> None:
        self.tree, self.robot, self.name = tree, robot, name
        self._emit = emit
        self._ended = ended  # (execution, result) -> why, from what the monitor heard
        self._dirty: dict[Node, State] = {}
        self._order: list[int] = []
        self._caps: set[Node] = set()
        self._runs: dict[Node, tuple[str, str]] = {}  # node -> (execution, executor)
        self._unobserve = tree.observe(self._changed)

    def close(self) -> None:
        self._unobserve()

    def _changed(self, node: Node, old: State, new: State) -> None:
        self._dirty[node] = new
        if self._caps and node in self._caps:
            self._capability(node, new)  # type: ignore[arg-type]

    def _capability(self, node: Capability, new: State) -> None:
        ex = node.execution
        cur = self._runs.get(node)
        now = self.tree.clock.now()
        if ex is not None:
            key = str(ex.id)
            if cur is not None and cur[0] == key:
                return
            if cur is not None:
                self._end(node, cur, "moved", now, f"moved to {ex.robot}")
            self._runs[node] = (key, ex.robot)
            self._emit(
                {
                    "t": now,
                    "k": "run",
                    "phase": "start",
                    "execution": key,
                    "robot": ex.robot,
                    "origin": self.robot,
                    "node": node.path,
                    "capability": type(node).INTERFACE.name,
                }
            )
        elif cur is not None:
            result = "lost" if new is _UNASSIGNED else new.value
            self._end(node, cur, result, now, self._ended(cur[0], result))

    def _end(self, node: Node, cur: tuple[str, str], result: str, now: float, why: Any) -> None:
        del self._runs[node]
        ev = {"t": now, "k": "run", "phase": "end", "execution": cur[0], "result": result}
        self._emit({**ev, "why": why})

    def structure(self) -> Event:
        """The whole tree as one event (sent at the start and whenever it changed)."""
        nodes = list(self.tree.nodes())
        self._order = [id(n) for n in nodes]
        caps = [n for n in nodes if isinstance(n, Capability)]
        self._caps = set(caps)
        for c in caps:
            if c.state not in DONE:
                self._capability(c, c.state)  # a run already under way when attached
        return {
            "t": self.tree.clock.now(),
            "k": "tree",
            "robot": self.robot,
            "tree": self.name,
            "nodes": [
                {
                    "id": n.path,
                    "name": n.name,
                    "type": type(n).__name__,
                    "parent": n.parent_node.path if n.parent_node is not None else None,
                    "cap": n in self._caps,
                    "state": n.state.value,
                }
                for n in nodes
            ],
        }

    def flush(self) -> Event | None:
        """The states changed since the last flush, or the whole tree if its shape changed."""
        if not self._dirty:
            return None
        dirty, self._dirty = self._dirty, {}
        if [id(n) for n in self.tree.nodes()] != self._order:
            return self.structure()
        states = {n.path: s.value for n, s in dirty.items()}
        now = self.tree.clock.now()
        return {"t": now, "k": "states", "robot": self.robot, "tree": self.name, "states": states}
