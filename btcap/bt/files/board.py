"""Blackboard entries of a BehaviorTree.CPP XML file, given to its trees as they are built.

The translation (:mod:`btcap.bt.files.btcpp`) wires an entry with one writer to its
readers; the entries wires cannot express become :class:`~btcap.bt.blackboard.Blackboard`
entries, listed per BehaviorTree in a :class:`TreeBoard`. :class:`Boards` gives each
tree the builder builds its blackboard: a SubTree's is remapped to its parent's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from btcap.bt.blackboard import Blackboard
from btcap.bt.files.btcpp_elements import literal
from btcap.bt.scripting.nodes import ScriptNode
from btcap.bt.state import TreeError
from btcap.bt.tree import Tree

__all__ = ["Boards", "TreeBoard"]


@dataclasses.dataclass
class TreeBoard:
    """What one BehaviorTree does with blackboard entries (node paths within it)."""

    #: (node path, input, entry) and (node path, output, entry).
    reads: list[tuple[str, str, str]] = dataclasses.field(default_factory=list)
    writes: list[tuple[str, str, str]] = dataclasses.field(default_factory=list)
    #: SubTree node path -> its tree's entry -> the entry of this tree it is.
    remaps: dict[str, dict[str, str]] = dataclasses.field(default_factory=dict)
    #: SubTree node path -> its tree's entry -> the literal it starts with.
    initial: dict[str, dict[str, str]] = dataclasses.field(default_factory=dict)
    #: Paths of the nodes running scripts over this tree's entries.
    scripts: list[str] = dataclasses.field(default_factory=list)


_Pending = tuple[Blackboard | None, dict[str, str], dict[str, str]]


class Boards:
    """The blackboards of the trees a builder is building, innermost last."""

    def __init__(
        self,
        specs: dict[str, TreeBoard],
        main: str,
        entries: Mapping[str, Any],
        enums: Mapping[str, int] | None = None,
    ) -> None:
        self.specs = specs
        self.enums = dict(enums or {})
        self.main = main
        #: What the application supplies, set on the main tree's board.
        self.entries = entries
        self.stack: list[tuple[Blackboard, TreeBoard, dict[str, str]]] = []
        #: What the next tree entered is: a SubTree's (parent, remap, initial values).
        self.next: _Pending | None = None

    def enter(self, tid: str) -> None:
        parent, remap, initial = self.next or (None, {}, {})
        self.next = None
        board = Blackboard(tid, parent, remap, parse=literal)
        self.stack.append((board, self.specs.get(tid) or TreeBoard(), initial))

    def hold(self) -> _Pending | None:
        """Take what :meth:`subtree` set (to build a tree definition on its own first)."""
        held, self.next = self.next, None
        return held

    def subtree(self, path: str) -> None:
        """The SubTree node at ``path`` is built next: its tree's board hangs on ours."""
        board, spec, _ = self.stack[-1]
        self.next = (board, spec.remaps.get(path, {}), spec.initial.get(path, {}))

    def leave(
        self, tree: Tree | None, fail: Callable[[str], None], ctx: str
    ) -> set[tuple[str, str]]:
        """Connect the built tree's nodes to its board; the (path, input)s it feeds."""
        board, spec, initial = self.stack.pop()
        fed: set[tuple[str, str]] = set()
        if tree is None:
            return fed
        tree.blackboard = board
        for path, port, key in spec.writes:
            try:
                board.write(tree.find(path), port, key)
            except TreeError as exc:
                fail(f"{ctx}node {path!r} output {port!r} (entry {{{key}}}): {exc}")
        for path, port, key in spec.reads:
            try:
                board.read(tree.find(path), port, key)
            except TreeError as exc:
                fail(f"{ctx}node {path!r} input {port!r} (entry {{{key}}}): {exc}")
            fed.add((path, port))
        for path in spec.scripts:
            node = tree.find(path)
            if isinstance(node, ScriptNode):
                node.bind(board, self.enums)
                for script in node.scripts().values():
                    for key in script.writes:
                        owner, name = board.owner(key)
                        owner.writers.setdefault(name, []).append(node.path)
        main = not self.stack and board.name == self.main
        values = {**initial, **self.entries} if main else initial
        for key, value in values.items():
            try:
                board[key] = value
            except TreeError as exc:
                fail(f"{ctx}{exc}")
        return fed
