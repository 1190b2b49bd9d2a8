"""How a failed ask crosses the wire: the :class:`Failure` reply, and the error it
becomes again on the asking side (a handler's own exception class may not exist there)."""

from __future__ import annotations

from typing import Any

from btcap.actors.errors import ActorError, ActorFailed, DeadLetter
from btcap.transports.message import Address, Message, MessageRegistry

__all__ = ["Failure", "error_of", "failure_of", "runtime_messages"]


class Failure(Message):
    """The reply to an ask whose handler raised or whose recipient does not exist."""

    error_type: str
    detail: str


def runtime_messages() -> MessageRegistry:
    """A registry holding the runtime's own message types."""
    return MessageRegistry([Failure])


def failure_of(error: BaseException) -> Failure:
    """The reply that tells the asker ``error``; an :class:`ActorFailed` passes on as it
    came, so a failure relayed through several systems still names the first."""
    if isinstance(error, ActorFailed):
        return Failure(error.error_type, error.detail)
    return Failure(type(error).__qualname__, str(error))


def error_of(sender: Address, msg: Any) -> ActorError:
    """What the asker raises for a failure reply ``msg`` from ``sender``: a missing
    recipient stays a :class:`DeadLetter`, anything else is :class:`ActorFailed`."""
    if not isinstance(msg, Failure):
        return ActorFailed(str(sender), "Unknown", repr(msg))
    if msg.error_type == "DeadLetter":
        return DeadLetter(f"{sender}: {msg.detail}")
    return ActorFailed(str(sender), msg.error_type, msg.detail)
