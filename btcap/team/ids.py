"""Typed identities of the team protocol, so nobody parses names out of strings.

Ids carry the ``incarnation`` of the robot that minted them (its membership's, fixed when
its agent starts and new after every restart): numbers restart at 1 in every process,
and a robot restarted under the same name must never mint an id its teammates still
remember from its previous life (they would decline its awards as "awarded before").
"""

from __future__ import annotations

import msgspec

__all__ = ["AuctionId", "ExecutionId", "check_robot_name", "incarnation_tag"]


def check_robot_name(name: str) -> str:
    """A robot name as the protocol uses it: non-empty, no ``/`` or ``:``, not ``*``."""
    if not name or "/" in name or ":" in name or name == "*" or not name.isprintable():
        raise ValueError(
            f"robot name {name!r}: expected a non-empty printable name without '/', ':'"
        )
    return name


def incarnation_tag(incarnation: int) -> str:
    """A short, log-friendly tag of an incarnation: ``~`` and its low 16 bits in hex (ids
    compare by the whole number; the tag only tells two lives apart in a log), or nothing
    for 0 (an id made by hand, outside a running robot)."""
    return f"~{incarnation & 0xFFFF:04x}" if incarnation else ""


class ExecutionId(msgspec.Struct, frozen=True, array_like=True):
    """One run of a capability node: the robot whose tree holds the node (its origin), the
    node's path, a number the origin never reuses in one life and the origin's
    incarnation, so no two lives of the origin share an id."""

    origin: str
    node: str
    number: int
    incarnation: int = 0

    def __str__(self) -> str:
        return f"{self.origin}{incarnation_tag(self.incarnation)}:{self.node}#{self.number}"


class AuctionId(msgspec.Struct, frozen=True, array_like=True):
    """One auction: who runs it, its number there and the auctioneer's incarnation (only
    the auctioneer may award)."""

    auctioneer: str
    number: int
    incarnation: int = 0

    def __str__(self) -> str:
        return f"{self.auctioneer}{incarnation_tag(self.incarnation)}#{self.number}"
