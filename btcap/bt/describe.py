"""What a tree says about each node beyond its shape, shared by tree files and rendering.

A node is described by the options and constant inputs that differ from their
declared defaults and by the wires feeding its inputs: exactly what a file writes to
rebuild the node, and what a picture of the tree shows. One description keeps the two
from drifting apart.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any

from btcap.bt.node import Node
from btcap.bt.tree import Tree

__all__ = ["InputKey", "NodeDescription", "describe", "same", "wire_sources"]

#: ``(id(target node), input name)``: one input of one node.
InputKey = tuple[int, str]


def same(a: Any, b: Any) -> bool:
    """Equal and of one type (``1`` is not ``1.0`` to a file); incomparable means different."""
    try:
        return bool(a == b) and type(a) is type(b)
    except Exception:
        return False


def wire_sources(tree: Tree) -> dict[InputKey, str]:
    """Every wired input of ``tree``, mapped to its source as ``node/path.output``."""
    return {(id(w.target), w.target_port): f"{w.source.path}.{w.source_port}" for w in tree.wires}


@dataclass(frozen=True, slots=True)
class NodeDescription:
    """The settings of one node that are not its defaults, in declaration order."""

    #: Options that are required or differ from their defaults (values as the node holds them).
    options: dict[str, Any]
    #: Constant inputs that differ from their defaults (never wired or fed ones).
    inputs: dict[str, Any]
    #: Wired inputs: input name -> ``node/path.output`` of the source.
    wired: dict[str, str]


def describe(
    node: Node, wires: Mapping[InputKey, str], *, fed: Collection[InputKey] = ()
) -> NodeDescription:
    """Describe ``node`` given its tree's :func:`wire_sources`.

    ``fed`` lists inputs given from outside the tree (a Subtree's public inputs): their
    current values come from the outer tree and are not the node's own settings.
    """
    options = {
        key: node.options.get(key)
        for key, port in type(node).OPTIONS.items()
        if port.required or not same(node.options.get(key), port.default_value())
    }
    inputs: dict[str, Any] = {}
    wired: dict[str, str] = {}
    for key, port in node.input_ports.items():
        at = (id(node), key)
        source = wires.get(at)
        if source is not None:
            wired[key] = source
        elif (
            at not in fed
            and key in node.inputs
            and not same(node.inputs[key], port.default_value())
        ):
            inputs[key] = node.inputs[key]
    return NodeDescription(options, inputs, wired)
