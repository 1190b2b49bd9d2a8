"""The remote capability slot: where a robot runs implementations for others."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

from btcap.actors.services import Service
from btcap.bt.node import Leaf
from btcap.bt.running import nudge_holder
from btcap.bt.state import State, TreeError
from btcap.team.capabilities.implementation import ImplementationRun
from btcap.team.core.hosting import Hosted
from btcap.team.ids import ExecutionId
from btcap.transports.log import get_logger

__all__ = ["SLOT_HOST", "RemoteCapabilitySlot", "SlotHost", "SlotWatcher"]

log = get_logger(__name__)

_RUNNING = State.RUNNING


@runtime_checkable
class SlotHost(Protocol):
    """What the slot needs from its robot's mission control."""

    def attach_slot(self, slot: RemoteCapabilitySlot) -> None: ...

    def hosted_ticked(
        self, hosted: Hosted[ImplementationRun], state: State, outputs: dict[str, Any]
    ) -> None: ...


#: The robot's :class:`SlotHost` among its actor system's services (its mission control).
SLOT_HOST: Service[SlotHost] = Service("slot host")

#: Told of a run the slot takes up (``why`` None) or puts down (``why``: ``finished``,
#: or why it was stopped: cancelled, its origin gone, its lease lapsed ...).
SlotWatcher = Callable[[Hosted[ImplementationRun], str | None], None]


class RemoteCapabilitySlot(Leaf):
    """A node in a robot's own tree that runs one remote-requested implementation at a time.

    The implementation is ticked at this tree's rate; its root state and outputs go back
    to the requesting robot after every tick. When it ends or is cancelled it is shut down
    and dropped, leaving nothing behind. The slot itself keeps running as a service.
    """

    __slots__ = ("_host", "_watchers", "current")

    def __init__(self, name: str | None = "slot", **kwargs: object) -> None:
        self.current: Hosted[ImplementationRun] | None = None
        self._host: SlotHost | None = None
        self._watchers: list[SlotWatcher] = []
        super().__init__(name, **kwargs)  # type: ignore[arg-type]

    def on_setup(self) -> None:
        system = self.tree.system
        host = system.services.get(SLOT_HOST) if system is not None else None
        if host is None:
            raise TreeError(f"slot {self.path!r}: the tree must be attached to a robot's system")
        host.attach_slot(self)
        self._host = host

    def load(self, hosted: Hosted[ImplementationRun]) -> str | None:
        """Take a run, or say why not."""
        if self.current is not None:
            return f"slot busy with {self.current.execution}"
        if not self._ready:
            return "slot not set up"
        hosted.run.tree.setup()
        hosted.run.tree.alarm.outer = self._tree  # news for its nodes: this tree ticks
        self.current = hosted
        self._tell(hosted, None)
        nudge_holder(self)  # its first tick now, not this tree's next period
        return None

    def unload(self, execution: ExecutionId, why: str = "unloaded") -> None:
        """Put the run of ``execution`` down (nothing if it is not the current one);
        ``why``: ``finished``, or why it was stopped, for the watchers."""
        hosted = self.current
        if hosted is not None and hosted.execution == execution:
            self.current = None
            self._tell(hosted, why)

    def _tell(self, hosted: Hosted[ImplementationRun], why: str | None) -> None:
        for watcher in tuple(self._watchers):  # (one may unsubscribe as it is told)
            try:
                watcher(hosted, why)
            except Exception as exc:  # an onlooker's fault must not stop the run
                log.error("slot.watcher_failed", execution=str(hosted.execution), exc_info=exc)

    def watch(self, watcher: SlotWatcher) -> Callable[[], None]:
        """Tell ``watcher`` of each run as the slot takes it up and puts it down (a
        monitor records a run shorter than its batches from this); nothing per tick.
        Returns an unsubscribe."""
        self._watchers.append(watcher)
        w = self._watchers
        return lambda: w.remove(watcher) if watcher in w else None

    def on_tick(self) -> State:
        h = self.current
        # A run acts only while leased (from its origin's first renewal until its lease
        # ends; mission control stops it then): a late tick must not act after that.
        if h is None or h.paused or self._host is None or not h.leased(self.clock.now()):
            return _RUNNING
        state, outputs = h.run.step(h.inputs)
        self._host.hosted_ticked(h, state, outputs)
        return _RUNNING

    def on_untick(self) -> None:
        if self.current is not None:
            self.current.run.pause()
