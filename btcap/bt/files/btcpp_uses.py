"""What a BehaviorTree.CPP XML tree does with its blackboard, for people to read.

The translation turns entries into wires or blackboard entries and forgets their
names; this keeps them: each node's ports that use an entry (``in goal <- {goal}``,
``out path -> {path}``, a script's reads and writes, a SubTree's remapped entries),
and the entries the application must set because a node reads them (in tree order,
depth first) before any node writes them. ``btcap tree show`` and ``dot`` print both;
``btcap tree run`` names each such entry it was not given (``--set``) before ticking.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from btcap.bt.files.btcpp_scope import Ref
from btcap.bt.tree import Tree

__all__ = ["EntryUses", "Needed", "entry_uses", "set_entry_uses"]

_ATTR = "entry_uses"
_ORDER = {"in": 0, "en": 1, "ou": 2, "sc": 3}


@dataclasses.dataclass(frozen=True)
class Needed:
    """An entry read before any node writes it: the first node reading it.

    In the main tree the application must set it; in a subtree the ``<SubTree>`` element
    named by ``via`` does not pass it in, so nobody can.
    """

    key: str
    tree: str
    path: str
    port: str  # "" for a script
    line: int
    where: str
    via: str = ""

    def describe(self) -> str:
        what = f"{self.path} ({self.port or 'script'})"
        if not self.via:
            return f"{{{self.key}}}: read by {what} before any node writes it"
        return (
            f"{{{self.key}}}: read by {what} in tree {self.tree!r} before any node writes "
            f'it, and {self.via} does not pass it in ({self.key}="{{...}}" or _autoremap)'
        )


@dataclasses.dataclass
class EntryUses:
    """Per (BehaviorTree ID, node path) the entry lines; the main tree's needed entries."""

    ports: dict[tuple[str, str], list[str]] = dataclasses.field(default_factory=dict)
    #: Per BehaviorTree ID, its entries read before any node writes them.
    first: dict[str, dict[str, Needed]] = dataclasses.field(default_factory=dict)
    #: Those no SubTree element passes into a subtree (nobody can set them).
    unpassed: list[Needed] = dataclasses.field(default_factory=list)

    def lines(self, tree: str, path: str) -> list[str]:
        """Inputs, a subtree's entries, outputs, then scripts."""
        return sorted(self.ports.get((tree, path), []), key=lambda t: _ORDER[t[:2]])

    def needed(self, main: str) -> list[Needed]:
        """What the application must set, then what nobody can set."""
        return [*self.first.get(main, {}).values(), *self.unpassed]

    def add(
        self,
        tree: str,
        key: str,
        refs: tuple[Sequence[Ref], Sequence[Ref], Sequence[tuple[Ref, bool]]],
        scripts: Sequence[tuple[Ref, bool]],
    ) -> None:
        """The lines of every port (and script) using entry ``key`` in ``tree``."""
        ws, rs, al = refs
        for r in rs:
            self._line(tree, r.path, f"in  {r.port} <- {{{key}}}")
        for w in ws:
            self._line(tree, w.path, f"out {w.port} -> {{{key}}}")
        for a, _ in al:
            self._line(tree, a.path, f"entry {{{a.port}}} is {{{key}}}")
        for s, writes in scripts:
            self._line(tree, s.path, f"script {'writes' if writes else 'reads'} {{{key}}}")

    def _line(self, tree: str, path: str, line: str) -> None:
        have = self.ports.setdefault((tree, path), [])
        if line not in have:
            have.append(line)

    def need(
        self,
        tree: str,
        key: str,
        refs: tuple[Sequence[Ref], Sequence[Ref], Sequence[tuple[Ref, bool]]],
        scripts: Sequence[tuple[Ref, bool]],
        order: dict[str, int],
        where: str,
    ) -> None:
        """Note ``key`` if a node reads it no later than the first node writing it."""
        ws, rs, al = refs
        reads = [*rs, *(a for a, w in al if not w), *(s for s, w in scripts if not w)]
        writes = [*ws, *(a for a, w in al if w), *(s for s, w in scripts if w)]
        last = len(order)
        first_write = min((order.get(w.path, last) for w in writes), default=last + 1)
        early = [r for r in reads if order.get(r.path, last) <= first_write]
        if early:
            r = min(early, key=lambda r: order.get(r.path, last))
            self.first.setdefault(tree, {})[key] = Needed(key, tree, r.path, r.port, r.line, where)

    def not_passed(self, tree: str, given: set[str], via: str) -> None:
        """A ``<SubTree>`` of ``tree`` passing only ``given`` (not _autoremap)."""
        for key, need in self.first.get(tree, {}).items():
            if key not in given and not key.startswith("@"):
                self.unpassed.append(dataclasses.replace(need, via=via))


def set_entry_uses(tree: Tree, uses: EntryUses) -> None:
    setattr(tree, _ATTR, uses)


def entry_uses(tree: Any) -> EntryUses | None:
    """What :func:`set_entry_uses` kept on a tree loaded from XML (None otherwise)."""
    uses = getattr(tree, _ATTR, None)
    return uses if isinstance(uses, EntryUses) else None
