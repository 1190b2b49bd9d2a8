"""What a strategy is asked to place, and what it answers (sans-IO values)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from btcap.team.core.auction import AuctionOutcome
from btcap.team.ids import ExecutionId

__all__ = ["Assigned", "AssignmentTask", "Unassigned", "against_holder"]


@dataclass(frozen=True, slots=True)
class AssignmentTask:
    """One capability execution to place on a robot."""

    execution: ExecutionId
    interface: str
    identity: str
    inputs: Mapping[str, Any]
    candidates: frozenset[str]
    lease_s: float
    reserve: float | None = None  # award only bids cheaper than this (moving running work)
    paused: bool = False  # the winner holds the run until its first inputs
    #: Re-evaluating running work: the execution and the robot running it (it bids what
    #: finishing would cost, is never awarded, and others must beat its bid by ``margin``).
    holder: ExecutionId | None = None
    holder_robot: str | None = None
    margin: float = 0.0
    #: An exchange: the robot running ``handing`` bids as if it handed it over, and holds
    #: the award paused beside it (:mod:`btcap.team.core.exchange`).
    handing: ExecutionId | None = None
    #: Added to the holder's bid after the margin (an exchange: what the other leg saves).
    credit: float = 0.0


@dataclass(frozen=True, slots=True)
class Assigned:
    """The robot that accepted, with the implementation it runs and its bid."""

    robot: str
    implementation: str
    cost: float
    held: float | None = None  # re-evaluation: the holder's fresh bid, if it made one
    #: The winner's clock in its acceptance (echoed to start the run; not compared).
    stamp: float | None = dataclasses.field(default=None, compare=False)


@dataclass(frozen=True, slots=True)
class Unassigned:
    """Nobody took the task, and why, robot by robot (for the log and the user)."""

    reasons: Mapping[str, str]


def against_holder(task: AssignmentTask, outcome: AuctionOutcome) -> AssignmentTask:
    """Re-evaluation: others must beat the holder's fresh bid by the margin (the holder
    itself is never awarded its own work again)."""
    if task.holder_robot is None:
        return task
    held = next((b.cost for b in outcome.ranking if b.robot == task.holder_robot), None)
    if held is None:  # no fresh bid to compare with: the work stays where it is
        return dataclasses.replace(task, reserve=0.0)
    beat = held * (1.0 - task.margin) + task.credit
    return dataclasses.replace(
        task, reserve=beat if task.reserve is None else min(task.reserve, beat)
    )
