"""A btcap tree written as BehaviorTree.CPP 4's ``WriteTreeToXML`` writes a running tree.

This is the XML a ``.btlog`` starts with and Groot2 draws: every node with its ``_uid``
(numbered depth first from 1, a SubTree's own nodes right after the SubTree node), each
subtree instance as a ``<BehaviorTree>`` of its own with its ``_fullpath``, and the node
models in ``<TreeNodesModel>``. A standard node is written under its BehaviorTree.CPP
name (btcap's ``LatchedIfThenElse`` is ``IfThenElse``) with its ports, defaults
included; a node of btcap's own is written under its type name, its model declaring its
ports. Only the models of the types the tree uses are written (BehaviorTree.CPP writes
every one it knows; Groot2 knows the built-in ones anyway).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any
from xml.sax.saxutils import escape

from btcap.bt.files.btcpp_nodes import STANDARD
from btcap.bt.leaves import Condition
from btcap.bt.node import Node
from btcap.bt.tree import Subtree, Tree

__all__ = ["UidNode", "btcpp_tag", "btcpp_xml", "numbered"]

#: BehaviorTree.CPP's name for each btcap type a standard node becomes.
_TAGS: dict[str, str] = {std.btcap: tag for tag, std in reversed(STANDARD.items())}
_TAGS["SequenceWithMemory"] = "SequenceWithMemory"  # btcap's own, decides as the standard one

#: Attribute value from the btcap option, by the converter that read it (inverse of it).
_FORMAT: dict[str, Any] = {
    # None: btcap's Parallel fails once success is lost, as BehaviorTree.CPP's does with -1
    "parse_int": lambda v: "-1" if v is None else str(v),
    "_cycles": str,
    "_attempts": lambda v: "-1" if v is None else str(v),
    "_seconds": lambda v: str(round(v * 1000)),
    "_timeout": lambda v: str(round(v * 1000)),
    "script_code": str,
    "_else": str,
    "parse_bool": lambda v: "true" if v else "false",
}

_INDENT = "    "

#: One node with its uid, its parent's uid (0 for a tree's root) and its subtree's path.
UidNode = tuple[int, Node, str]


def btcpp_tag(node: Node) -> str:
    """The element name BehaviorTree.CPP gives ``node``: its registration name."""
    if isinstance(node, Subtree):
        return "SubTree"
    name = type(node).__name__
    return _TAGS.get(name, name)


def numbered(tree: Tree) -> list[UidNode]:
    """Every node with its BehaviorTree.CPP uid, in uid order: depth first, entering each
    Subtree right after its node (``(uid, node, path of the subtree it belongs to)``)."""
    out: list[UidNode] = []

    def visit(node: Node, path: str) -> None:
        out.append((len(out) + 1, node, path))
        if isinstance(node, Subtree):
            visit(node.inner.root, _subpath(path, node, len(out)))
        for child in node.children:
            visit(child, path)

    visit(tree.root, "")
    return out


def _subpath(path: str, node: Subtree, uid: int) -> str:
    """A SubTree instance's ``_fullpath``: its name, or ``ID::uid`` when it has none."""
    own = node.name if node.name != node.inner.name else f"{node.inner.name}::{uid}"
    return f"{path}/{own}" if path else own


def _attr(key: str, value: str) -> str:
    return f' {key}="{escape(value, {chr(34): "&quot;"})}"'


def _ports(node: Node) -> str:
    std = STANDARD.get(btcpp_tag(node))
    if std is None:
        return ""
    out = ""
    for key, (option, convert) in sorted(std.attrs.items()):
        if convert.__name__ == "_no_skip":
            out += _attr(key, "false")
        elif option in node.options:
            out += _attr(key, _FORMAT[convert.__name__](node.options[option]))
    return out


def _elements(node: Node, uids: dict[int, int], paths: dict[int, str], depth: int) -> str:
    pad = _INDENT * depth
    uid = uids[id(node)]
    if isinstance(node, Subtree):
        head = f"<SubTree{_attr('ID', node.inner.name)}{_attr('_fullpath', paths[id(node)])}"
        return f"{pad}{head}{_attr('_uid', str(uid))}/>\n"
    head = f"<{btcpp_tag(node)}{_attr('name', node.name)}{_attr('_uid', str(uid))}{_ports(node)}"
    if not node.children:
        return f"{pad}{head}/>\n"
    inner = "".join(_elements(c, uids, paths, depth + 1) for c in node.children)
    return f"{pad}{head}>\n{inner}{pad}</{btcpp_tag(node)}>\n"


def _kind(node: Node) -> str:
    if isinstance(node, Subtree):
        return "SubTree"
    if isinstance(node, Condition) or btcpp_tag(node) == "ScriptCondition":
        return "Condition"
    most = type(node).MAX_CHILDREN
    if most == 1:
        return "Decorator"
    return "Action" if most == 0 else "Control"


def _model(node: Node) -> str:
    tag = btcpp_tag(node)
    head = f"{_INDENT * 2}<{_kind(node)}{_attr('ID', tag)}"
    if tag in STANDARD or isinstance(node, Subtree):
        return f"{head}/>\n"
    ports = [
        f"{_INDENT * 3}<{kind}{_attr('name', key)}/>\n"
        for kind, table in (("input_port", node.input_ports), ("output_port", node.output_ports))
        for key in table
    ]
    return f"{head}>\n{''.join(ports)}{_INDENT * 2}</{_kind(node)}>\n" if ports else f"{head}/>\n"


def _instances(nodes: list[UidNode]) -> Iterator[tuple[str, str, Node]]:
    """(tree ID, _fullpath, root) of the main tree and each subtree instance, in uid order."""
    seen: set[str] = set()
    for uid, node, path in nodes:
        if uid == 1:
            yield "", "", node
        if isinstance(node, Subtree):
            sub = _subpath(path, node, uid)
            if sub not in seen:
                seen.add(sub)
                yield node.inner.name, sub, node.inner.root


def btcpp_xml(tree: Tree, nodes: list[UidNode] | None = None) -> str:
    """The tree as BehaviorTree.CPP's ``WriteTreeToXML(tree, true, ...)`` text."""
    nodes = numbered(tree) if nodes is None else nodes
    uids = {id(n): uid for uid, n, _ in nodes}
    paths = {id(n): _subpath(path, n, uid) for uid, n, path in nodes if isinstance(n, Subtree)}
    body = ""
    for tree_id, path, root in _instances(nodes):
        tid = tree_id or tree.name
        body += f"{_INDENT}<BehaviorTree{_attr('ID', tid)}{_attr('_fullpath', path)}>\n"
        body += _elements(root, uids, paths, 2)
        body += f"{_INDENT}</BehaviorTree>\n"
    models = {btcpp_tag(n): n for _, n, _ in sorted(nodes, key=lambda e: btcpp_tag(e[1]))}
    body += f"{_INDENT}<TreeNodesModel>\n{''.join(_model(n) for n in models.values())}"
    return f'<root BTCPP_format="4">\n{body}{_INDENT}</TreeNodesModel>\n</root>\n'
