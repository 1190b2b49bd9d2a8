"""Errors the actor runtime raises to callers."""

from __future__ import annotations

from btcap.errors import BtcapError

__all__ = [
    "ActorError",
    "ActorFailed",
    "AskTimeout",
    "DeadLetter",
    "MailboxFull",
    "Refused",
    "SystemClosed",
]


class ActorError(BtcapError):
    """Base of every error the runtime raises."""


class ActorFailed(ActorError):
    """The handler of an ask raised; carries the remote error's type and text."""

    def __init__(self, address: str, error_type: str, detail: str) -> None:
        super().__init__(f"{address} failed handling the request: {error_type}: {detail}")
        self.address = address
        self.error_type = error_type
        self.detail = detail


class AskTimeout(ActorError, TimeoutError):
    """No reply came in time."""


class DeadLetter(ActorError):
    """The recipient does not exist (never did, or was stopped)."""


class MailboxFull(ActorError):
    """The recipient's bounded mailbox is full."""


class Refused(ActorError):
    """The recipient takes this message only from inside its own actor system (a
    ``local_only`` handler, such as a BT node's actions), and it came from a transport."""


class SystemClosed(ActorError):
    """The actor system shut down while a request was pending."""
