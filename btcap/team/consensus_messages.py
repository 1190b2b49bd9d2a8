"""Messages of consensus allocation (no auctioneer): the tasks an origin offers, robots'
claims to them, and the prices an origin posts (:mod:`btcap.team.allocation.consensus`).

Named in :mod:`btcap.team.messages` with the rest of the capability layer's messages, and
registered with them by :func:`btcap.team.runtime.protocol.protocol_registry`."""

from __future__ import annotations

from typing import Any

import msgspec

from btcap.team.ids import ExecutionId
from btcap.transports.message import Message

__all__ = ["ConsensusClaim", "ConsensusPrices", "ConsensusTasks", "OpenTask"]


class OpenTask(msgspec.Struct, frozen=True, array_like=True):
    """One capability execution an origin wants run, as consensus allocation offers it.
    ``holder``: running work is re-evaluated; ``holder_robot`` runs it and its bid counts
    ``margin`` lower, so others must beat it by that much."""

    execution: ExecutionId
    interface: str
    identity: str
    inputs: dict[str, Any]
    candidates: list[str]
    holder: ExecutionId | None = None
    holder_robot: str | None = None
    margin: float = 0.0
    #: The origin's clock speed-up (0: a virtual clock, or not said): a robot whose clock
    #: runs at another rate claims none of its tasks, saying why (as it declines a call
    #: for bids: :class:`~btcap.team.messages.CallForBids`).
    speedup: float = 0.0


class ConsensusTasks(Message):
    """The sender's open tasks as of ``version`` (newer versions replace older ones)."""

    robot: str
    version: int
    tasks: list[OpenTask]


class ConsensusClaim(Message):
    """The sender's claim to a task's origin (``task`` at ``cost`` with ``implementation``,
    bidding the price ``bid``; or none) under its ``stamp``, made having merged the
    origin's task set ``seen``; ``most``: its dearest cost among the open tasks (the
    origin's ceiling follows it); ``why``: tasks it cannot bid for, and why. ``seq``
    grows with every message of the sender; ``view`` is unused (kept for older peers)."""

    robot: str
    seq: int
    stamp: int
    task: ExecutionId | None
    cost: float
    implementation: str
    view: list[tuple[str, int, int]]
    why: list[tuple[ExecutionId, str]] = []
    bid: float = 0.0
    most: float = 0.0
    seen: int = 0


class ConsensusPrices(Message):
    """An origin's price board in its task set ``version``, numbered ``seq``, sent to a
    robot that must bid again: (task, price, holder) for each open task; ``heard``: the
    recipient's newest claim stamp it reflects; ``ceiling``: the cost of claiming
    nothing."""

    robot: str
    version: int
    seq: int
    heard: int
    prices: list[tuple[ExecutionId, float, str | None]]
    ceiling: float
