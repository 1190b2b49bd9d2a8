"""The origin's handle on a capability execution, and the request that finds one."""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from typing import Any, Protocol

from btcap.bt.state import State
from btcap.team.ids import ExecutionId

__all__ = ["AssignmentRequest", "Execution"]


class Execution(Protocol):
    """The origin side of a running implementation, local or on another robot."""

    id: ExecutionId
    robot: str

    def step(self, inputs: Mapping[str, Any]) -> tuple[State | None, dict[str, Any]]:
        """Send inputs, return the latest (state, outputs); state None: the executor is lost
        or the work moved (see :meth:`hand_over`)."""

    def pause(self) -> None: ...

    def cancel(self, reason: str) -> None: ...

    def hand_over(self) -> Execution | None:
        """The execution that takes over from this one (work moved to a cheaper robot)."""

    def moving(self) -> bool:
        """Whether a replacement waits to be adopted (and this run has not finished)."""


class AssignmentRequest:
    """An assignment in progress; the capability node polls ``done`` on its ticks."""

    __slots__ = ("cancelled", "done", "execution", "task", "why")

    def __init__(self) -> None:
        self.done = False
        self.cancelled = False
        self.execution: Execution | None = None
        self.task: asyncio.Task[Any] | None = None
        #: Done without an execution: why each robot could not take it (robot -> reason).
        self.why: dict[str, str] = {}

    def cancel(self) -> None:
        self.cancelled = True
        if self.execution is not None:
            self.execution.cancel("request cancelled")
            self.execution = None
        if self.task is not None:
            self.task.cancel()
