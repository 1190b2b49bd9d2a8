"""The actor runtime: typed actors, addresses, tell/ask, supervision, dead letters."""

from btcap.actors.actor import Actor
from btcap.actors.cell import ActorCell, Reply, Supervision
from btcap.actors.clock import Clock, ManualClock, TimeSource, within
from btcap.actors.errors import (
    ActorError,
    ActorFailed,
    AskTimeout,
    DeadLetter,
    MailboxFull,
    Refused,
    SystemClosed,
)
from btcap.actors.failure import Failure, runtime_messages
from btcap.actors.handlers import handler
from btcap.actors.log import configure_logging
from btcap.actors.ref import ActorRef
from btcap.actors.services import Service, Services
from btcap.actors.stats import SystemStats
from btcap.actors.system import ActorSystem
from btcap.transports.message import Address, Message

__all__ = [
    "Actor",
    "ActorCell",
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
    "Refused",
    "Reply",
    "Service",
    "Services",
    "Supervision",
    "SystemClosed",
    "SystemStats",
    "TimeSource",
    "configure_logging",
    "handler",
    "runtime_messages",
    "within",
]
