"""The node actions as typed messages, so a node can be driven by another actor.

Nodes take them only from inside their own actor system: across a transport they are
refused (a remote run is driven through its handle, never node by node). They are in the
protocol registry so a refusal and its reason reach the sender.
"""

from __future__ import annotations

from typing import Any

from btcap.bt.state import State
from btcap.transports.message import Message

__all__ = [
    "NODE_MESSAGES",
    "NodeStatus",
    "Reset",
    "Setup",
    "Shutdown",
    "Tick",
    "Untick",
]


class Setup(Message):
    """Prepare a node for ticking."""


class Tick(Message):
    """Tick a node, first giving it these input values."""

    inputs: dict[str, Any] = {}


class Untick(Message):
    """Pause a node's work."""


class Reset(Message):
    """Return a node to idle."""


class Shutdown(Message):
    """Release a node's resources."""


class NodeStatus(Message):
    """A node's state and outputs, the reply to every node action."""

    state: State
    outputs: dict[str, Any] = {}


NODE_MESSAGES: tuple[type[Message], ...] = (Setup, Tick, Untick, Reset, Shutdown, NodeStatus)
