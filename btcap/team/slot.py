"""The remote capability slot: where a robot runs implementations for others."""

from __future__ import annotations

from typing import TYPE_CHECKING

from btcap.bt.node import Leaf
from btcap.bt.state import State, TreeError

if TYPE_CHECKING:
    from btcap.team.mission import Hosted, MissionControl

__all__ = ["RemoteCapabilitySlot"]

_RUNNING = State.RUNNING


class RemoteCapabilitySlot(Leaf):
    """A node in a robot's own tree that runs one remote-requested implementation at a time.

    The implementation is ticked at this tree's rate; its root state and outputs go back
    to the requesting robot after every tick. When it ends or is cancelled it is shut down
    and dropped, leaving nothing behind. The slot itself keeps running as a service.
    """

    __slots__ = ("_mc", "current")

    def __init__(self, name: str | None = "slot", **kwargs: object) -> None:
        self.current: Hosted | None = None
        self._mc: MissionControl | None = None
        super().__init__(name, **kwargs)  # type: ignore[arg-type]

    def on_setup(self) -> None:
        from btcap.team.mission import MissionControl

        system = self.tree.system
        mc = system.lookup(MissionControl.PATH) if system is not None else None
        if not isinstance(mc, MissionControl):
            raise TreeError(f"slot {self.path!r}: the tree must be attached to a robot's system")
        mc.attach_slot(self)
        self._mc = mc

    def load(self, hosted: Hosted) -> str | None:
        """Take a run, or say why not."""
        if self.current is not None:
            return f"slot busy with {self.current.id}"
        if not self._ready:
            return "slot not set up"
        hosted.run.tree.setup()
        self.current = hosted
        return None

    def unload(self, hosted: Hosted) -> None:
        if self.current is hosted:
            self.current = None

    def on_tick(self) -> State:
        h = self.current
        if h is None or h.paused or self._mc is None:
            return _RUNNING
        state, outputs = h.run.step(h.inputs)
        self._mc.hosted_ticked(h, state, outputs)
        return _RUNNING

    def on_untick(self) -> None:
        if self.current is not None:
            self.current.run.pause()
