"""The actor base class users subclass: a cell with its typed system and ref."""

from __future__ import annotations

from typing import Any

from btcap.actors.cell import ActorCell
from btcap.actors.ref import ActorRef
from btcap.actors.system import ActorSystem

__all__ = ["Actor"]


class Actor(ActorCell):
    """Base class of everything addressable: BT nodes, slots, repositories, auctioneers.

    Declare handlers with :func:`~btcap.actors.handlers.handler`; see
    :class:`~btcap.actors.cell.ActorCell` for how messages are delivered.
    """

    __slots__ = ()

    # Narrowed: only ActorSystem.spawn sets a cell's host.
    _system: ActorSystem | None

    @property
    def system(self) -> ActorSystem:
        if self._system is None:
            raise RuntimeError(f"{type(self).__name__} is not spawned in an actor system")
        return self._system

    @property
    def ref(self) -> ActorRef[Any]:
        return ActorRef(self.address, self.system, self)
