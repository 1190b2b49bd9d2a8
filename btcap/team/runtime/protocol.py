"""The registry of every message a robot speaks: runtime, node actions and team protocol."""

from __future__ import annotations

from btcap.actors import runtime_messages
from btcap.bt.messages import NODE_MESSAGES
from btcap.team.messages import CAPABILITY_MESSAGES
from btcap.transports import MessageRegistry

__all__ = ["protocol_registry"]


def protocol_registry() -> MessageRegistry:
    """A fresh registry with every message btcap and its runtime speak."""
    reg = runtime_messages()
    reg.register(*NODE_MESSAGES, *CAPABILITY_MESSAGES)
    return reg
