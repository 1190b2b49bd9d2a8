"""Handles to actors: local ones are called directly, remote ones go through the transport."""

from __future__ import annotations

import asyncio
from typing import Any, Generic, TypeVar, overload

from btcap.actors.cell import ActorCell, Host
from btcap.transports.message import Address

__all__ = ["ActorRef"]

A = TypeVar("A", bound=ActorCell)
R = TypeVar("R")


class ActorRef(Generic[A]):
    """A sendable handle: ``tell`` fires and forgets, ``ask`` awaits a typed reply."""

    __slots__ = ("_local", "_system", "address")

    def __init__(self, address: Address, system: Host, local: A | None = None) -> None:
        self.address = address
        self._system = system
        self._local = local

    def __repr__(self) -> str:
        return f"ActorRef({self.address})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ActorRef) and other.address == self.address

    def __hash__(self) -> int:
        return hash(self.address)

    @property
    def is_local(self) -> bool:
        return self.address.system == self._system.id

    def tell(self, msg: Any, *, sender: Address | None = None) -> None:
        """Send without waiting; failures to deliver become dead letters, never errors."""
        actor = self._local
        if actor is not None and actor._system is not None:
            actor._receive(msg, None)
        else:
            self._system.tell(self.address, msg, sender=sender)

    @overload
    async def ask(self, msg: Any, *, timeout: float | None = None) -> Any: ...
    @overload
    async def ask(
        self,
        msg: Any,
        *,
        expect: type[R],
        timeout: float | None = None,
    ) -> R: ...
    async def ask(
        self,
        msg: Any,
        *,
        expect: type[Any] | None = None,
        timeout: float | None = None,
    ) -> Any:
        """Request and await the reply: ``timeout`` seconds of the wall on a real clock,
        of the clock on a virtual one (where wall time must decide nothing).

        Raises :class:`~actors.errors.ActorFailed` if the handler raised,
        :class:`~actors.errors.AskTimeout` if no reply came, and ``TypeError`` if the
        reply is not of the ``expect``-ed type.
        """
        actor = self._local
        if actor is not None and actor._can_call_now(msg):
            result = actor._call_now(msg)
            if isinstance(result, asyncio.Future):
                result = await self._system.await_deferred(self.address, msg, result, timeout)
        else:
            result = await self._system.ask(self.address, msg, timeout=timeout)
        if expect is not None and not isinstance(result, expect):
            raise TypeError(
                f"reply of {self.address} to {type(msg).__qualname__}: expected "
                f"{expect.__qualname__}, got {type(result).__qualname__}"
            )
        return result
