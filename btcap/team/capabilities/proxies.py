"""The origin's handles on its executions, ticked by the capability node.

A :class:`LocalExecution` is a run this robot won in its own auction: the node ticks it
directly. A :class:`RemoteExecution` sends the node's inputs to the executor every tick
and returns the state and outputs the executor last reported (the origin's lease table
keeps them). Either may carry a *replacement* while the work is being moved to a cheaper
robot; the node adopts it through :meth:`hand_over`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from btcap.bt.state import State
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.implementation import ImplementationRun
from btcap.team.capabilities.remote_error import tell_remote_error
from btcap.team.core.body import Body
from btcap.team.core.origin import Tracked
from btcap.team.ids import ExecutionId
from btcap.team.messages import (
    RUN_DONE,
    CancelExecution,
    ExecutionInputs,
    PauseExecution,
    RunState,
)

__all__ = ["HandleOwner", "LocalExecution", "RemoteExecution"]

#: What the capability node makes of a remote run's reported state (same values; LOST
#: never reaches the node: the lease table gives the execution up instead).
_NODE_STATE = {s: State(s.value) for s in RunState}


class HandleOwner(Protocol):
    """What the handles need from their robot's mission control."""

    robot: str
    body: Body

    def send(self, robot: str, msg: Any) -> None: ...

    def let_go(self, ex: LocalExecution | RemoteExecution, reason: str) -> None: ...

    def fenced(self, execution: ExecutionId) -> bool: ...

    def release(self, execution: ExecutionId, run: ImplementationRun) -> None: ...

    def record_success(self, capability: str) -> None: ...


class _Handle:
    __slots__ = ("_side", "cost", "id", "node", "replacement", "robot")

    def __init__(
        self, side: HandleOwner, execution: ExecutionId, robot: str, node: Capability, cost: float
    ) -> None:
        self._side = side
        self.id = execution
        self.robot = robot
        self.node = node
        self.cost = cost
        self.replacement: LocalExecution | RemoteExecution | None = None

    def hand_over(self) -> LocalExecution | RemoteExecution | None:
        """The execution taking over from this one, now the caller's to hold."""
        nxt, self.replacement = self.replacement, None
        return nxt if nxt is not None and not nxt.lost else None

    def _moving(self) -> bool:
        """A replacement waits to be adopted (one lost on the way is forgotten)."""
        nxt = self.replacement
        if nxt is not None and nxt.lost:
            self.replacement = nxt = None
        return nxt is not None


class LocalExecution(_Handle):
    """The origin won its own auction: the capability node ticks the run directly (not
    before every run of the task given up on elsewhere surely stopped)."""

    __slots__ = ("live", "run")

    def __init__(
        self,
        side: HandleOwner,
        execution: ExecutionId,
        run: ImplementationRun,
        node: Capability,
        cost: float,
    ) -> None:
        super().__init__(side, execution, side.robot, node, cost)
        self.run = run
        self.live = False
        # The node ticks the run: news for the run's nodes (a ROS goal answered) is its tree's.
        run.tree.alarm.outer = node._tree

    @property
    def lost(self) -> bool:
        return False

    def moving(self) -> bool:
        return self.replacement is not None and self._moving()

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        if self.replacement is not None and self._moving():
            return None, {}  # moved: the node adopts the replacement
        if self._side.body.running != self.id:
            return State.ASSIGNED, {}  # queued behind this robot's current work
        if not self.live:
            if self._side.fenced(self.id):
                return State.ASSIGNED, {}  # its task's run given up elsewhere may still act
            self.live = True
        state, outputs = self.run.step(inputs)
        if state is State.SUCCEEDED:
            self._side.record_success(self.run.implementation.interface.name)
        return state, outputs

    def pause(self) -> None:
        self.run.pause()
        if self.replacement is not None:
            self.replacement.pause()

    def cancel(self, reason: str) -> None:
        self._side.let_go(self, reason)
        self._side.release(self.id, self.run)


class RemoteExecution(_Handle):
    """The origin's proxy of a run in another robot's slot: inputs out, status back."""

    __slots__ = ("tracked",)

    def __init__(self, side: HandleOwner, tracked: Tracked, node: Capability, cost: float) -> None:
        super().__init__(side, tracked.execution, tracked.executor, node, cost)
        self.tracked = tracked

    @property
    def lost(self) -> bool:
        return self.tracked.lost

    @property
    def state(self) -> RunState:
        return self.tracked.state

    def moving(self) -> bool:
        t = self.tracked
        return (
            not t.lost
            and self.replacement is not None
            and t.state not in RUN_DONE
            and (self._moving())
        )

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        t = self.tracked
        if t.lost or (self.replacement is not None and t.state not in RUN_DONE and self._moving()):
            return None, {}  # lost, or moved: the node adopts the replacement
        if not t.live:  # awarded paused: its inputs start it, once no other run may act
            if self._side.fenced(self.id):
                return State.ASSIGNED, {}
            t.live = True
        if t.state is RunState.ERROR:  # ended: the origin's user hears why, not only that
            tell_remote_error(self.node, self.node.interface().name, self.robot, t.detail)
            return State.ERROR, t.outputs
        t.seq += 1
        self._side.send(self.robot, ExecutionInputs(self.id, t.seq, dict(inputs), t.stamp))
        return _NODE_STATE[t.state], t.outputs

    def pause(self) -> None:
        if not self.tracked.lost:
            self._side.send(self.robot, PauseExecution(self.id))
        if self.replacement is not None:
            self.replacement.pause()

    def cancel(self, reason: str) -> None:
        self._side.let_go(self, reason)
        if not self.tracked.lost:
            self._side.send(self.robot, CancelExecution(self.id, reason))
