"""Which BehaviorTree.CPP blackboard entries of an XML tree can be wires, and their type.

:mod:`btcap.bt.files.btcpp` wires an entry's one writer to its readers only where a wire
reads what the entry would hold (:func:`before`); the others become blackboard entries,
whose ports must agree on one type (:func:`entry_type`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from btcap.bt.files.schema import NodeSpec
from btcap.bt.ports import assignable, type_name

__all__ = ["before", "entry_type", "merged", "passing", "paths"]

T = TypeVar("T")

#: btcap node types that tick their children in order, each only after the one before
#: succeeded in the same run; and those that succeed only when their child just did.
_SEQUENCES = frozenset(
    {"Sequence", "SequenceWithMemory", "ReactiveSequence", "AsyncSequence"}
    | {"AsyncSequenceWithMemory"}
)
_PASSING = _SEQUENCES | {"Timeout", "RepeatUntilSuccess", "Repeat", "Delay"}


def paths(spec: NodeSpec, parent: str | None) -> Iterator[tuple[str, NodeSpec]]:
    """(path, spec) of every node of a translated tree (the reader names every node)."""
    name = spec.name or spec.type
    path = name if parent is None else f"{parent}/{name}"
    yield path, spec
    for child in spec.children:
        yield from paths(child, path)


def passing(path: list[str], start: int, specs: dict[str, NodeSpec]) -> bool:
    """Whether every node from ``path[:start + 1]`` down to (not including) the last
    succeeds only when the one below it succeeded in the same run."""
    return all(specs["/".join(path[: i + 1])].type in _PASSING for i in range(start, len(path) - 1))


def merged(refs: dict[str, list[T]], main: bool) -> dict[str, list[T]]:
    """Entries by name; in the main tree ``{@key}`` is ``{key}``."""
    if not main:
        return refs
    out: dict[str, list[T]] = {}
    for key, some in refs.items():
        out.setdefault(key.removeprefix("@"), []).extend(some)
    return out


def before(writer: str, reader: str, specs: dict[str, NodeSpec]) -> bool:
    """Whether the node at ``reader`` ticks only after the one at ``writer`` succeeded in
    the same run: both under one sequence, the writer's branch first and made of nodes
    that succeed only when the one below them did (a wire then reads what the entry
    would hold)."""
    w, r = writer.split("/"), reader.split("/")
    k = 0
    while k < min(len(w), len(r)) - 1 and w[k] == r[k]:
        k += 1
    lca = specs.get("/".join(w[:k])) if k and w[:k] == r[:k] else None
    if lca is None or lca.type not in _SEQUENCES:
        return False
    names = [c.name for c in lca.children]
    return names.index(w[k]) < names.index(r[k]) and passing(w, k, specs)


def entry_type(
    key: str,
    written: list[tuple[int, Any]],
    read: list[tuple[int, Any]],
    fail: Callable[[int, str], None],
) -> Any:
    """The one type of an entry, from the (line, type)s that write and read it; writers
    of different types, or a reader the writers' type does not fit, are reported."""
    typed = [(line, tp) for line, tp in written if tp is not Any]
    for line, tp in typed[1:]:
        if not (assignable(tp, typed[0][1]) and assignable(typed[0][1], tp)):
            fail(
                line,
                f"{{{key}}} is written as {type_name(tp)} here and as "
                f"{type_name(typed[0][1])} at line {typed[0][0]}; an entry has one type",
            )
    for line, tp in read if typed else ():
        if not assignable(typed[0][1], tp):
            fail(
                line,
                f"{{{key}}} is read here as {type_name(tp)} but written as "
                f"{type_name(typed[0][1])} at line {typed[0][0]}",
            )
    return typed[0][1] if typed else next((t for _, t in read if t is not Any), Any)
