"""Typed identities of the team protocol, so nobody parses names out of strings."""

from __future__ import annotations

import msgspec

__all__ = ["AuctionId", "ExecutionId", "check_robot_name"]


def check_robot_name(name: str) -> str:
    """A robot name as the protocol uses it: non-empty, no ``/`` or ``:``, not ``*``."""
    if not name or "/" in name or ":" in name or name == "*" or not name.isprintable():
        raise ValueError(
            f"robot name {name!r}: expected a non-empty printable name without '/', ':'"
        )
    return name


class ExecutionId(msgspec.Struct, frozen=True, array_like=True):
    """One run of a capability node: the robot whose tree holds the node (its origin), the
    node's path and a number the origin never reuses."""

    origin: str
    node: str
    number: int

    def __str__(self) -> str:
        return f"{self.origin}:{self.node}#{self.number}"


class AuctionId(msgspec.Struct, frozen=True, array_like=True):
    """One auction: who runs it and its number there (only the auctioneer may award)."""

    auctioneer: str
    number: int

    def __str__(self) -> str:
        return f"{self.auctioneer}#{self.number}"
