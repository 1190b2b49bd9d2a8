"""The actor runtime: typed actors, addresses, tell/ask, supervision, dead letters."""

from actors.actor import Actor, Reply, Supervision, handler
from actors.clock import Clock, ManualClock, TimeSource
from actors.errors import (
    ActorError,
    ActorFailed,
    AskTimeout,
    DeadLetter,
    MailboxFull,
    SystemClosed,
)
from actors.log import configure_logging
from actors.ref import ActorRef
from actors.system import ActorSystem, Failure, SystemStats, runtime_messages
from transports.message import Address, Message

__all__ = [
    "Actor",
    "ActorError",
    "ActorFailed",
    "ActorRef",
    "ActorSystem",
    "Address",
    "AskTimeout",
    "Clock",
    "DeadLetter",
    "Failure",
    "MailboxFull",
    "ManualClock",
    "Message",
    "Reply",
    "Supervision",
    "SystemClosed",
    "SystemStats",
    "TimeSource",
    "configure_logging",
    "handler",
    "runtime_messages",
]
