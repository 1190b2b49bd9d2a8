"""Data wires: an output of one node feeding an input of another, held by their tree."""

from __future__ import annotations

from btcap.bt.node import Node

__all__ = ["Wire"]


class Wire:
    """An output of one node feeding an input of another, pulled when the input's node ticks."""

    __slots__ = ("source", "source_port", "target", "target_port")

    def __init__(self, source: Node, source_port: str, target: Node, target_port: str) -> None:
        self.source = source
        self.source_port = source_port
        self.target = target
        self.target_port = target_port

    def __repr__(self) -> str:
        return (
            f"Wire({self.source.path}.{self.source_port} -> {self.target.path}.{self.target_port})"
        )
