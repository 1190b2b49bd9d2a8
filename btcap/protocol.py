"""btcap's typed protocol messages; every one of them survives the codec."""

from __future__ import annotations

from typing import Any

from actors import Message, runtime_messages
from btcap.state import State
from transports import MessageRegistry

__all__ = [
    "NodeStatus",
    "Reset",
    "Setup",
    "Shutdown",
    "Tick",
    "Untick",
    "protocol_registry",
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


def protocol_registry() -> MessageRegistry:
    """A fresh registry with every message btcap and its runtime speak."""
    from btcap.messages import CAPABILITY_MESSAGES

    reg = runtime_messages()
    reg.register(*NODE_MESSAGES, *CAPABILITY_MESSAGES)
    return reg
