"""A BehaviorTree.CPP-style blackboard: named entries that several nodes read and write.

btcap's own trees wire one node output to inputs; a blackboard is for the cases wires
cannot say, which BehaviorTree.CPP XML trees use: entries the application supplies
before ticking, entries several nodes write (the last write wins), a node reading and
writing the same entry, and ``{@key}`` entries of the root blackboard. A tree that uses
no entry has no blackboard and pays nothing for it.

A node input fed from an entry reads the entry's current value when the node ticks; an
entry never written (nor supplied) makes a required input fail the node, as
BehaviorTree.CPP's ``getInput`` fails (an input with a default gets its default). A node
output writing an entry writes it whenever the node sets that output; None is "no value"
in btcap (what a reset leaves), so setting None leaves the entry as it was.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, cast

from btcap.bt.ports import ENTRY, Missing, Port, check_port, type_name
from btcap.bt.state import TreeError

if TYPE_CHECKING:
    from btcap.bt.node import Node

__all__ = ["Blackboard"]


class _Entries(dict[str, Any]):
    """Entry values; an entry never written reads as :class:`Missing`."""

    __slots__ = ()

    def __missing__(self, key: str) -> Missing:
        return Missing(key)


class _Writes(dict[str, Any]):
    """A node's outputs that also write blackboard entries when set (None excepted)."""

    __slots__ = ("to",)

    to: dict[str, tuple[Blackboard, str]]

    def __setitem__(self, key: str, value: Any) -> None:
        dict.__setitem__(self, key, value)
        if value is not None:
            target = self.to.get(key)
            if target is not None:
                board, name = target
                entries = board.outputs
                if name not in entries:
                    board._arrived(name)
                entries[name] = value


class Blackboard:
    """The entries of one tree (a Subtree instance has its own, remapped to its parent's).

    ``remap`` maps an entry of this blackboard to an entry of ``parent`` (BehaviorTree.CPP's
    SubTree port remapping): both names are then one entry. ``parse`` converts text an
    application supplies for an entry of another type (BehaviorTree.CPP converts strings
    on reading); without it, values are only checked.
    """

    __slots__ = (
        "name",
        "outputs",
        "parent",
        "parse",
        "ports",
        "readers",
        "remap",
        "waiting",
        "writers",
    )

    def __init__(
        self,
        name: str = "",
        parent: Blackboard | None = None,
        remap: dict[str, str] | None = None,
        parse: Callable[[str, Any], Any] | None = None,
    ) -> None:
        self.name = name
        self.parent = parent
        self.remap = dict(remap or {})
        self.parse: Callable[[str, Any], Any] | None = (
            parse if parse is not None or parent is None else parent.parse
        )
        #: Entry values (named like a node's outputs, so a node input pulls from it as
        #: from a node's output: reading costs what a wire costs).
        self.outputs: _Entries = _Entries()
        #: Declared types of the entries this blackboard holds.
        self.ports: dict[str, Port] = {}
        self.readers: dict[str, list[str]] = {}
        self.writers: dict[str, list[str]] = {}
        #: Inputs checked on every tick until their entry has a value: (node, input,
        #: its port) per entry.
        self.waiting: dict[str, list[tuple[Node, str, Port]]] = {}

    # -- entries ----------------------------------------------------------------------
    def owner(self, key: str) -> tuple[Blackboard, str]:
        """The blackboard holding ``key`` and its name there (``@key``: the root's)."""
        board, name = self, key
        if name.startswith("@"):
            while board.parent is not None:
                board = board.parent
            return board, name[1:]
        while name in board.remap and board.parent is not None:
            board, name = board.parent, board.remap[name]
            if name.startswith("@"):
                return board.owner(name)
        return board, name

    def declare(self, key: str, port: Port) -> None:
        """Say which type ``key`` holds (the first typed declaration stands)."""
        board, name = self.owner(key)
        known = board.ports.get(name)
        if known is None or (known.type is Any and port.type is not Any):
            board.ports[name] = Port(port.type, description=port.description)

    def __contains__(self, key: object) -> bool:
        if not isinstance(key, str):
            return False
        board, name = self.owner(key)
        return name in board.outputs

    def __getitem__(self, key: str) -> Any:
        board, name = self.owner(key)
        if name not in board.outputs:
            raise KeyError(key)
        return board.outputs[name]

    def get(self, key: str, default: Any = None) -> Any:
        try:
            return self[key]
        except KeyError:
            return default

    def __setitem__(self, key: str, value: Any) -> None:
        """Set an entry, checked against its declared type (text is parsed to it)."""
        board, name = self.owner(key)
        port = board.ports.get(name)
        if port is None:
            known = ", ".join(sorted(board.ports)) or "none"
            raise TreeError(
                f"blackboard {board.name!r}: no entry {name!r} that the application can "
                f"set (entries: {known})"
            )
        if isinstance(value, str) and board.parse is not None:
            value = board.parse(value, port.type)
        where = f"blackboard entry {name!r} of tree {board.name!r}"
        value = check_port(value, port, where)
        if name not in board.outputs:
            board._arrived(name)
        board.outputs[name] = value

    def _arrived(self, name: str) -> None:
        """Entry ``name`` has its first value: its inputs need no check any more, reading
        it costs what reading a wire does."""
        for node, port, inp in self.waiting.pop(name, ()):
            node.input_ports[port] = inp
            node._regate()

    def __iter__(self) -> Iterator[str]:
        return iter(self.ports)

    def __repr__(self) -> str:
        return f"<Blackboard {self.name!r} {dict(self.outputs)!r}>"

    def check(self, tree: str) -> None:
        """Raise TreeError if a required input reads an entry no node writes and nobody set."""
        needed = []
        for key, readers in self.readers.items():
            if readers and not self.writers.get(key) and key not in self.outputs:
                tp = type_name(self.ports[key].type) if key in self.ports else "Any"
                needed.append(f"{{{key}}} ({tp}, read by {', '.join(readers)})")
        if needed:
            raise TreeError(
                f"tree {tree!r}: blackboard entries read but never written nor set: "
                f"{'; '.join(needed)}; set them before ticking (tree.blackboard[KEY] = "
                f"VALUE, or btcap tree run --set KEY=VALUE)"
            )

    # -- wiring nodes -----------------------------------------------------------------
    def read(self, node: Node, port: str, key: str) -> None:
        """Feed ``node``'s input ``port`` from entry ``key`` on every tick of the node."""
        inp = node.input_ports.get(port)
        if inp is None:
            raise TreeError(f"node {node.path!r} has no input {port!r}")
        board, name = self.owner(key)
        board.declare(name, inp)
        if inp.required:
            board.readers.setdefault(name, []).append(f"{node.path}.{port}")
        if inp.meta is None and name not in board.outputs:  # checked until it has a value
            node.input_ports = {**node.input_ports, port: dataclasses.replace(inp, meta=ENTRY)}
            board.waiting.setdefault(name, []).append((node, port, inp))
        if node._pulls is None:
            node._pulls = []
        node._pulls.append((port, cast("Node", board), name))
        node._regate()

    def write(self, node: Node, port: str, key: str) -> None:
        """Write entry ``key`` whenever ``node`` sets its output ``port``.

        A :class:`~btcap.bt.tree.Subtree`'s output is written by the inner node behind
        it, as in BehaviorTree.CPP, where the two share the entry.
        """
        while True:
            inner = getattr(node, "_out_map", None)
            if inner is None or port not in inner:
                break
            node, port = inner[port]
        out = node.output_ports.get(port)
        if out is None:
            raise TreeError(f"node {node.path!r} has no output {port!r}")
        board, name = self.owner(key)
        board.declare(name, out)
        board.writers.setdefault(name, []).append(f"{node.path}.{port}")
        outputs = node.outputs
        if not isinstance(outputs, _Writes):
            outputs = _Writes(outputs)
            outputs.to = {}
            node.outputs = outputs
        outputs.to[port] = (board, name)
