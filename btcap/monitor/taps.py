"""Where a monitor's node events come from: one tap per tree.

A tap costs the ticking tree one call per node transition, which are rare (a tick
mostly leaves every state as it was): capability nodes' transitions make the timeline
and are reported at once, with their clock time; any other only marks the tap changed.
The states are read when the monitor flushes (at most 20 times a second), only in a tap
marked changed (most batches of a ``--fast`` run have none: no walk), and only the nodes
whose state differs from the last batch are sent: a page sees the latest state of each
node per batch, as it would from coalesced changes.

The implementation a :class:`~btcap.team.capabilities.slot.RemoteCapabilitySlot` runs for another
robot is a tree of its own: it is shown below the slot while it runs. The runs a slot
takes up and puts down are reported at once too (the slot tells the tap, nothing per
tick): a hosted run may start and end between two batches, and the recording of a robot
whose origins are elsewhere (``btcap agent --record``) would not hold it otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from btcap.bt.node import Node
from btcap.bt.state import DONE, State
from btcap.bt.tree import Tree
from btcap.monitor.view import Event
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.implementation import ImplementationRun
from btcap.team.capabilities.slot import RemoteCapabilitySlot
from btcap.team.core.hosting import Hosted
from btcap.team.messages import RUN_DONE, RunState

__all__ = ["Emit", "TreeTap"]

#: Hands one event to the monitor (which stamps nothing: events carry their own time).
Emit = Callable[[Event], None]

_UNASSIGNED = State.UNASSIGNED


class TreeTap:
    """Observes one tree of one robot: states batched, capability runs at once."""

    def __init__(
        self,
        tree: Tree,
        robot: str,
        name: str,
        emit: Emit,
        ended: Callable[[str, str], str | None],
        hosted: Emit | None = None,
    ) -> None:
        self.tree, self.robot, self.name = tree, robot, name
        self._emit = emit
        self._ended = ended  # (execution, result) -> why, from what the monitor heard
        self._hosted = hosted or emit  # the runs its slots take up and put down
        self._watched: dict[RemoteCapabilitySlot, Callable[[], None]] = {}
        #: The paths of the tree's capability nodes (their runs are reported from them).
        self.capabilities: frozenset[str] = frozenset()
        self._nodes: list[Node] = []  # in tree order, as last sent
        self._shape: tuple[int, ...] = (-1,)  # the tree's version and the slots' runs
        self._slots: list[RemoteCapabilitySlot] = []
        self._paths: list[str] = []
        self._sent: list[State] = []
        self._runs: dict[Node, tuple[str, str]] = {}  # node -> (execution, executor)
        self._changed_since = True  # a node changed state since the last batch
        self._unobserve = tree.observe(self._changed)
        self._unhosted: list[Callable[[], None]] = []  # the hosted runs' trees observed

    def close(self) -> None:
        self._unobserve()
        self._unobserve_hosted()
        for unwatch in self._watched.values():
            unwatch()
        self._watched.clear()

    def _unobserve_hosted(self) -> None:
        for undo in self._unhosted:
            undo()
        self._unhosted.clear()

    def _changed(self, node: Node, old: State, new: State) -> None:
        self._changed_since = True
        if isinstance(node, Capability):
            self._capability(node, new)

    def _hosted_changed(self, node: Node, old: State, new: State) -> None:
        self._changed_since = True

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

    def _slot_run(self, hosted: Hosted[ImplementationRun], why: str | None) -> None:
        """A slot of this tree took up a run for another robot (``why`` None) or put it
        down: its result if it finished, else ``stopped`` and why."""
        self._changed_since = True
        ex = hosted.execution
        ev: Event = {"t": self.tree.clock.now(), "k": "run", "execution": str(ex)}
        if why is None:
            capability = hosted.run.implementation.interface.name
            where = {"robot": self.robot, "origin": ex.origin, "node": ex.node}
            self._hosted({**ev, "phase": "start", **where, "capability": capability})
            return
        state = hosted.state
        if state in RUN_DONE:
            detail = hosted.run.why_error() if state is RunState.ERROR else ""
            self._hosted({**ev, "phase": "end", "result": state.value, "why": detail or None})
        else:
            self._hosted({**ev, "phase": "end", "result": "stopped", "why": why})

    def _watch_slots(self) -> None:
        """Hear of the runs of this tree's slots (and of no slot it no longer has)."""
        for slot in [s for s in self._watched if s not in self._slots]:
            self._watched.pop(slot)()
        for slot in self._slots:
            if slot not in self._watched:
                self._watched[slot] = slot.watch(self._slot_run)
                if slot.current is not None:  # a run already under way when attached
                    self._slot_run(slot.current, None)

    def _shape_now(self) -> tuple[int, ...]:
        shape = [self.tree.version]
        for slot in self._slots:
            run = slot.current
            shape += (id(run.run.tree), run.run.tree.version) if run is not None else (0, 0)
        return tuple(shape)

    def _reshaped(self) -> bool:
        """Whether the shape differs from the last :meth:`structure`'s, read in place:
        this runs at every batch, and nearly always finds it the same (no tuple built)."""
        shape = self._shape
        if self.tree.version != shape[0]:
            return True
        i = 1
        for slot in self._slots:
            run = slot.current
            if run is None:
                if shape[i]:
                    return True
            elif shape[i] != id(tree := run.run.tree) or shape[i + 1] != tree.version:
                return True
            i += 2
        return False

    def structure(self) -> Event:
        """The whole tree as one event (sent at the start and whenever it changed)."""
        own = list(self.tree.nodes())
        self._slots = [n for n in own if isinstance(n, RemoteCapabilitySlot)]
        self.capabilities = frozenset(n.path for n in own if isinstance(n, Capability))
        self._watch_slots()
        self._unobserve_hosted()
        nodes: list[Node] = []
        parents: list[str | None] = []
        paths: list[str] = []
        for n in own:
            nodes.append(n)
            paths.append(n.path)
            parents.append(n.parent_node.path if n.parent_node is not None else None)
            hosted = n.current if isinstance(n, RemoteCapabilitySlot) else None
            if hosted is not None:
                self._unhosted.append(hosted.run.tree.observe(self._hosted_changed))
            for m in hosted.run.tree.nodes() if hosted is not None else ():
                nodes.append(m)
                paths.append(f"{n.path}/{m.path}")
                parents.append(
                    n.path if m.parent_node is None else f"{n.path}/{m.parent_node.path}"
                )
        self._nodes, self._paths, self._shape = nodes, paths, self._shape_now()
        self._sent = [n.state for n in nodes]
        self._changed_since = False
        for n in own:
            if isinstance(n, Capability) and n.state not in DONE:
                self._capability(n, n.state)  # a run already under way when attached
        return {
            "t": self.tree.clock.now(),
            "k": "tree",
            "robot": self.robot,
            "tree": self.name,
            "nodes": [
                {
                    "id": path,
                    "name": n.name,
                    "type": type(n).__name__,
                    "parent": parent,
                    "cap": isinstance(n, Capability),
                    "state": n.state.value,
                }
                for n, path, parent in zip(nodes, paths, parents, strict=True)
            ],
        }

    def flush(self) -> Event | None:
        """The states changed since the last flush, or the whole tree if its shape changed
        (nodes came or went, or a slot took up or put down a run)."""
        if self._reshaped():
            return self.structure()
        if not self._changed_since:
            return None
        self._changed_since = False
        sent = self._sent
        states: dict[str, str] = {}
        for i, n in enumerate(self._nodes):
            state = n.state
            if state is not sent[i]:
                sent[i] = state
                states[self._paths[i]] = state.value
        if not states:
            return None
        now = self.tree.clock.now()
        return {"t": now, "k": "states", "robot": self.robot, "tree": self.name, "states": states}
