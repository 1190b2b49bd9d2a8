"""Messages an observer exchanges with robots (``btcap team status``): how each robot
sees its team, and who failed or left lately. Re-exported by
:mod:`btcap.team.messages`, which registers them with the rest of the protocol."""

from __future__ import annotations

import msgspec

from btcap.team.ids import ExecutionId
from btcap.transports.message import Message

__all__ = ["Departed", "Departures", "DeparturesQuery", "Seen", "StatusQuery", "TeamStatus"]


# -- observers ---------------------------------------------------------------------------
class StatusQuery(Message):
    """How is the team, as you see it? (asked by an observer, which is never a member)"""


class Seen(msgspec.Struct, frozen=True, array_like=True):
    """A teammate as the answering robot sees it."""

    robot: str
    endpoint: str
    heartbeat_age_ms: int


class TeamStatus(Message):
    """A robot's answer to :class:`StatusQuery`: itself (what it offers, completed, runs,
    holds queued) and the members it sees, with where they listen."""

    robot: str
    interfaces: dict[str, str]
    succeeded: list[str]
    running: list[ExecutionId]
    queued: list[ExecutionId]
    members: list[Seen]


# -- departures (btcap team status) ------------------------------------------------------
class Departed(msgspec.Struct, frozen=True, array_like=True):
    """A robot that left the team or was declared failed, as one teammate saw it."""

    robot: str
    incarnation: int
    #: "failed" or "left".
    how: str
    #: How long ago, in milliseconds of the teller's clock (no two hosts' clocks agree).
    age_ms: int
    why: str = ""


class DeparturesQuery(Message):
    """Who failed or left lately? (asked by ``btcap team status``)"""


class Departures(Message):
    """The latest departures a robot saw, the most recent first (a bounded few)."""

    robot: str
    departed: list[Departed]
