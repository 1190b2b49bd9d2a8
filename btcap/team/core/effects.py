"""What the sans-IO core asks its shell to do: it decides, the shell performs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from btcap.team.ids import ExecutionId

__all__ = ["Drop", "Effect", "Lost", "Pause", "Refused", "Send", "Start"]


@dataclass(frozen=True, slots=True)
class Send:
    """Tell ``message`` to the mission control of robot ``to``."""

    to: str
    message: Any


@dataclass(frozen=True, slots=True)
class Refused:
    """Input that was not ``sender``'s to send (or made no sense): count it, log one line."""

    sender: str
    message: Any
    why: str


@dataclass(frozen=True, slots=True)
class Lost:
    """Origin side: the executor of ``execution`` is gone; its node re-assigns the work."""

    execution: ExecutionId
    executor: str
    why: str


@dataclass(frozen=True, slots=True)
class Drop:
    """Executor side: stop and remove ``run``, the run of ``execution`` (its share of the
    body is already released)."""

    execution: ExecutionId
    why: str
    run: Any


@dataclass(frozen=True, slots=True)
class Pause:
    """Executor side: pause the run of ``execution`` and keep it."""

    execution: ExecutionId


@dataclass(frozen=True, slots=True)
class Start:
    """Executor side: the queued ``execution`` now has the body; set its run up."""

    execution: ExecutionId


Effect = Send | Refused | Lost | Drop | Pause | Start
