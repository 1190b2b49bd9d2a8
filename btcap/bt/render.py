"""Trees as text (for terminals and logs) and as Graphviz DOT (for pictures).

Both show what a file says: node types and names, options that differ from their
defaults, constant inputs and data wires; once a tree has been ticked they also show
each node's state, and outputs as values.
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from btcap.bt.composites import Composite
from btcap.bt.decorators import Decorator
from btcap.bt.describe import NodeDescription, describe, wire_sources
from btcap.bt.node import Node
from btcap.bt.ports import type_name
from btcap.bt.state import State
from btcap.bt.tree import Subtree, Tree

__all__ = ["EntryLines", "render_dot", "render_text"]

#: (tree name, node path within it) -> lines saying which entries the node's ports use
#: (a BehaviorTree.CPP file's ``{goal}``: :mod:`btcap.bt.files.btcpp_uses`).
EntryLines = Callable[[str, str], list[str]]

_STATE_COLOURS = {
    State.UNINITIALIZED: "white",
    State.IDLE: "white",
    State.RUNNING: "lightskyblue",
    State.SUCCEEDED: "palegreen",
    State.FAILED: "salmon",
    State.ERROR: "red",
    State.SHUTDOWN: "lightgrey",
    State.PAUSED: "khaki",
    State.UNASSIGNED: "plum",
    State.ASSIGNED: "orchid",
    State.SKIPPED: "lightgrey",
}


def _ticked(tree: Tree) -> bool:
    return tree.root.state is not State.UNINITIALIZED


def _fmt(value: Any, limit: int = 60) -> str:
    """A short readable value; types by name, long values cut."""
    if value is Any or isinstance(value, type) or typing.get_origin(value) is not None:
        text = type_name(value)
    else:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _options(about: NodeDescription) -> list[str]:
    return [f"{key}={_fmt(value)}" for key, value in about.options.items()]


def _detail_lines(
    node: Node, about: NodeDescription, states: bool, entries: list[str]
) -> list[str]:
    lines = []
    named = set()  # ports shown by their entry (and the wire it became, if it did)
    for line in entries:
        key = line.split()[1]
        named.add(key)
        wired = about.wired.get(key) if line.startswith("in ") else None
        lines.append(f"{line} (wire from {wired})" if wired else line)
    for key in node.input_ports:
        if key in named:
            continue
        if key in about.wired:
            lines.append(f"in  {key} <- {about.wired[key]}")
        elif key in about.inputs:
            lines.append(f"in  {key} = {_fmt(about.inputs[key])}")
    if states:
        for key, value in node.outputs.items():
            if value is not None:
                lines.append(f"out {key} = {_fmt(value)}")
    if node.error is not None:
        lines.append(f"error: {type(node.error).__name__}: {node.error}")
    return lines


def _head(node: Node, about: NodeDescription, states: bool) -> str:
    kind = type(node).__name__
    if isinstance(node, Subtree):
        head = f"{kind} {node.name!r} (tree {node.inner.name!r})"
    else:
        head = f"{kind} {node.name!r}"
    opts = _options(about) if not isinstance(node, Subtree) else []
    if opts:
        head += "  " + " ".join(opts)
    if states:
        head += f"  [{node.state.value}]"
    return head


def _no_entries(tree: str, path: str) -> list[str]:
    return []


def render_text(
    tree: Tree, *, states: bool | None = None, entries: EntryLines | None = None
) -> str:
    """An indented outline of the tree; ``states`` defaults to "if it has been ticked"."""
    show = _ticked(tree) if states is None else states
    n_nodes = sum(1 for _ in tree.nodes())
    lines = [f"tree {tree.name!r}: {n_nodes} nodes, {len(tree.wires)} wires"]
    rows = _Rows(show, entries or _no_entries)
    lines.extend(rows.lines(tree.name, wire_sources(tree), tree.root, "", ""))
    return "\n".join(lines) + "\n"


class _Rows:
    """The outline's lines, node by node."""

    def __init__(self, states: bool, entries: EntryLines) -> None:
        self.states = states
        self.entries = entries

    def lines(
        self, tree: str, wires: dict[tuple[int, str], str], node: Node, first: str, rest: str
    ) -> Iterator[str]:
        about = describe(node, wires)
        yield first + _head(node, about, self.states)
        kids = [(tree, wires, c) for c in node.children]
        if isinstance(node, Subtree):
            kids.append((node.inner.name, wire_sources(node.inner), node.inner.root))
        bar = "│   " if kids else "    "
        uses = self.entries(tree, node.path)
        for line in _detail_lines(node, about, self.states, uses):
            yield rest + bar + "· " + line
        for i, (t, w, child) in enumerate(kids):
            last = i == len(kids) - 1
            yield from self.lines(
                t,
                w,
                child,
                rest + ("└── " if last else "├── "),
                rest + ("    " if last else "│   "),
            )


def _q(text: str) -> str:
    """A DOT double-quoted string."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _shape(node: Node) -> tuple[str, str]:
    if isinstance(node, Subtree):
        return "folder", "filled"
    if isinstance(node, Composite):
        return "box", "rounded,filled"
    if isinstance(node, Decorator):
        return "hexagon", "filled"
    return "ellipse", "filled"


def render_dot(
    tree: Tree,
    *,
    states: bool | None = None,
    entries: EntryLines | None = None,
    note: Sequence[str] = (),
) -> str:
    """Graphviz DOT: solid child edges, dashed data wires labelled ``output -> input``.

    ``note``: lines drawn in a note beside the tree (what the application must set).

    Subtrees are drawn as clusters below their Subtree node. Node ids are node paths
    (prefixed by the Subtree node's path inside subtrees), so they are unique.
    """
    show = _ticked(tree) if states is None else states
    out = [
        f"digraph {_q(tree.name)} {{",
        "  rankdir=TB;",
        '  node [fontname="Helvetica", fontsize=11];',
        '  edge [fontname="Helvetica", fontsize=9];',
    ]
    _dot_tree(tree, "", out, "  ", (show, entries or _no_entries))
    if note:
        out.append(f"  {_q('note')} [shape=note, label={_q(chr(10).join(note))}];")
    out.append("}")
    return "\n".join(out) + "\n"


def _dot_tree(
    tree: Tree, prefix: str, out: list[str], indent: str, how: tuple[bool, EntryLines]
) -> None:
    states, entries = how

    def ident(node: Node) -> str:
        return _q(prefix + node.path)

    wires = wire_sources(tree)
    for node in tree.nodes():
        shape, style = _shape(node)
        label = [type(node).__name__, node.name, *_options(describe(node, wires))]
        label += entries(tree.name, node.path)
        if states:
            label.append(f"[{node.state.value}]")
        colour = _STATE_COLOURS[node.state] if states else "white"
        out.append(
            f"{indent}{ident(node)} [label={_q(chr(10).join(label))}, shape={shape}, "
            f'style="{style}", fillcolor={colour}];'
        )
    for node in tree.nodes():
        for child in node.children:
            out.append(f"{indent}{ident(node)} -> {ident(child)};")
    for w in tree.wires:
        out.append(
            f"{indent}{ident(w.source)} -> {ident(w.target)} [style=dashed, color=blue, "
            f"fontcolor=blue, constraint=false, "
            f"label={_q(f'{w.source_port} -> {w.target_port}')}];"
        )
    for node in tree.nodes():
        if isinstance(node, Subtree):
            inner_prefix = f"{prefix}{node.path}::"
            cluster = _q(f"cluster_{inner_prefix}")
            out.append(f"{indent}subgraph {cluster} {{")
            out.append(f"{indent}  label={_q(f'subtree {node.inner.name}')};")
            out.append(f"{indent}  style=dashed;")
            _dot_tree(node.inner, inner_prefix, out, indent + "  ", how)
            out.append(f"{indent}}}")
            out.append(
                f"{indent}{ident(node)} -> {_q(inner_prefix + node.inner.root.path)} "
                f"[style=dotted, arrowhead=none];"
            )
