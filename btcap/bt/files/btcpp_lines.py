"""Where a BehaviorTree.CPP XML problem is: its file and line, in the reader's order.

Problems the builder finds name a node by its path; the translator knows the XML line
of every node and wire, so the user reads the line of the file they edit.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from btcap.bt.files.xmlread import XmlElement

__all__ = ["Lines", "check_subtree_model", "insert_problem", "relabel"]

_LINE = re.compile(r"^(.*?): line (\d+): ")
_WHERE = re.compile(
    r"^(?:subtree '(?P<tree>[^']+)' )?(?:node '(?P<path>[^']+)'|wires\[(?P<i>\d+)\])"
)


class Lines(Protocol):
    """What a translator records of where things are."""

    main: str
    tree_where: dict[str, str]
    node_lines: dict[tuple[str, str], int]
    wire_lines: dict[tuple[str, int], int]


def insert_problem(problems: list[str], problem: str) -> None:
    """Put ``problem`` before the first one of its file at a later line."""
    m = _LINE.match(problem)
    if m is None:  # the closing "what to do" line
        problems.append(problem)
        return
    for i, other in enumerate(problems):
        n = _LINE.match(other)
        if n is not None and n.group(1) == m.group(1) and int(n.group(2)) > int(m.group(2)):
            problems.insert(i, problem)
            return
    problems.append(problem)


class Ports(Protocol):
    """A translated BehaviorTree's public ports, and the entries only unknown types use."""

    @property
    def inputs(self) -> Mapping[str, Any]: ...
    @property
    def outputs(self) -> Mapping[str, Any]: ...
    @property
    def unsure(self) -> frozenset[str]: ...


def check_subtree_model(
    models: dict[str, XmlElement], tid: str, ports: Ports, fail: Callable[[int, str], None]
) -> None:
    """A ``<SubTree>`` entry of TreeNodesModel must agree with what the tree does (a port
    only a node of unknown type may use is that type's problem, reported as such)."""
    model = models.get(tid)
    if model is None or model.tag != "SubTree":
        return
    del models[tid]  # checked once, at its first use
    inputs, outputs = ports.inputs, ports.outputs
    for port in model.children:
        key = port.attrs.get("name", "")
        if key in ports.unsure:
            continue
        if port.tag == "input_port" and key not in inputs:
            fail(
                port.line,
                f"<TreeNodesModel> SubTree {tid!r} input_port {key!r}: the tree does not "
                f"read {{{key}}} from outside (it reads: {', '.join(inputs) or 'nothing'})",
            )
        elif port.tag == "output_port" and key not in outputs:
            fail(
                port.line,
                f"<TreeNodesModel> SubTree {tid!r} output_port {key!r}: the tree does not "
                f"write {{{key}}} (it writes: {', '.join(outputs) or 'nothing'})",
            )


def relabel(problems: list[str], where: str, t: Lines) -> list[str]:
    """Builder problems (named by node path) with the XML line of the node or wire."""
    out = []
    prefix = f"{where}: "
    for p in problems:
        rest = p.removeprefix(prefix)
        m = _WHERE.match(rest)
        line = None
        at = where
        if m is not None:
            tree = m.group("tree") or t.main
            at = t.tree_where.get(tree, where)
            if m.group("path") is not None:
                line = t.node_lines.get((tree, m.group("path")))
            else:
                line = t.wire_lines.get((tree, int(m.group("i"))))
        out.append(p if line is None else f"{at}: line {line}: {rest}")
    return out
