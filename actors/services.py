"""Services: what the parts of one actor system share, found by a typed key, not a path.

A behaviour-tree node built from a file cannot be handed its robot's mission control in
its constructor, yet it needs it when it runs; it asks its tree's actor system for the
service instead. The key is an object typed with what it stands for, so ``get`` returns
that type (a path string returned an actor cell of any type, to be checked by hand).
"""

from __future__ import annotations

from typing import Generic, TypeVar, cast

__all__ = ["Service", "Services"]

T = TypeVar("T")


class Service(Generic[T]):
    """The key of one service, e.g. ``ASSIGNER: Service[Assigner] = Service("assigner")``.

    Keys compare by identity: the name is only for messages.
    """

    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f"Service({self.name!r})"


class Services:
    """The services of one actor system (``ActorSystem.services``)."""

    __slots__ = ("_by_key",)

    def __init__(self) -> None:
        self._by_key: dict[Service[object], object] = {}

    def provide(self, key: Service[T], value: T) -> None:
        """Offer ``value`` as ``key``; one system has one provider of each service."""
        held = self._by_key.get(cast("Service[object]", key), value)
        if held is not value:
            raise ValueError(f"{key!r} is already provided by {held!r}")
        self._by_key[cast("Service[object]", key)] = value

    def get(self, key: Service[T]) -> T | None:
        """The value provided as ``key``, or None."""
        return cast("T | None", self._by_key.get(cast("Service[object]", key)))
