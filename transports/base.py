"""What an actor system needs from a transport, and the counters every transport keeps."""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from anyio.abc import TaskStatus

from btcap.transports.codec import Envelope
from btcap.transports.message import Message

__all__ = ["BROADCAST", "Deliver", "Transport", "TransportStats"]

#: The system id that addresses every peer of the team at once.
BROADCAST = "*"

Deliver = Callable[[Envelope], None]


@dataclass(slots=True)
class TransportStats:
    """Counters so dropped input is visible, never silent."""

    sent: int = 0
    received: int = 0
    malformed: int = 0
    unknown_peer: int = 0
    undeliverable: int = 0
    by_reason: dict[str, int] = field(default_factory=dict)
    #: Peers that refused our handshake, and what to check, until one admits us.
    refused_by: dict[str, str] = field(default_factory=dict)

    def drop(self, reason: str) -> None:
        self.by_reason[reason] = self.by_reason.get(reason, 0) + 1


class Transport(abc.ABC):
    """Moves envelopes between actor systems.

    ``send`` never blocks and never raises for a peer that is gone: delivery between
    robots is best effort, and the protocols above rely on leases and timeouts.
    """

    system_id: str
    stats: TransportStats

    @abc.abstractmethod
    async def serve(self, deliver: Deliver, *, task_status: TaskStatus[None]) -> None:
        """Receive until cancelled, handing every valid envelope to ``deliver``."""

    @abc.abstractmethod
    def send(self, env: Envelope) -> None:
        """Send to ``env.recipient.system``; a recipient system of ``*`` means every peer."""

    @abc.abstractmethod
    def peers(self) -> frozenset[str]:
        """The system ids this transport can currently reach."""

    def unreachable(self) -> frozenset[str]:
        """Peers whose recent dials all failed (nobody listens where they said they do):
        worth suspecting at once. Empty where a transport cannot tell (in-process)."""
        return frozenset()

    def introduce(self, system_id: str, endpoint: str) -> bool:
        """Reach a system a teammate told us of; whether it is (now) reachable.

        Transports that reach every system without being told (in-process) need nothing.
        """
        return system_id in self.peers()

    def forget(self, system_id: str) -> None:
        """``system_id`` has gone (the layer above declared it failed or left): release
        what reaching it costs. Transports that hold nothing per peer need nothing."""
        return None

    def limit(self, table: Mapping[str, frozenset[type[Message]] | None] | None) -> None:
        """What each authenticated role may send (role -> message types, None: any).
        Transports that authenticate no roles (in-process) ignore it."""
        del table

    def members(self, check: Callable[[str], bool] | None) -> None:
        """Who is a member of the team (``check(peer)``): others' messages are held to a
        smaller size. Transports that decode nothing from peers (in-process) ignore it."""
        del check

    def role_of(self, peer: str) -> str | None:
        """A peer's authenticated role, None where roles are not known (no keys)."""
        return None

    def endpoint_of(self, system_id: str) -> str | None:
        """Where ``system_id`` (or this system) can be reached, if this transport dials."""
        return None
