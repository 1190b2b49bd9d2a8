"""The extension point for allocation strategies: what a strategy is told, what it decides.

A :class:`Strategy` has a ``name`` and makes, for each robot of a team, the
:class:`Allocator` that places that robot's capability executions. It is **told**:

- once per robot, a :class:`RobotContext`: the robot's name, its settings (the auction
  window, the award timeout...), its view of the team (who is alive; joins, failures,
  robots coming free) and its :class:`Pricer` (what this robot would bid for a call);
- then each :class:`~btcap.team.core.task.AssignmentTask` (:meth:`Allocator.assign`):
  the interface, inputs, candidate robots and lease, and for re-evaluated running work
  the reserve, holder and margin;
- and whatever its own actors on the other robots tell it (it is an actor, spawned at
  ``Allocator.PATH`` on every robot of the team).

It **decides** who runs each task: :class:`~btcap.team.core.task.Assigned` once the
robot accepted the award (an ``Award`` ask to its mission control, so a busy robot can
still decline), or :class:`~btcap.team.core.task.Unassigned` with why, robot by robot.

Strategies are registered by name (:mod:`btcap.team.allocation.strategies`: the built-ins and the
``btcap.strategies`` entry-point group) and given to an agent by name or as an object
(``Agent(strategy=...)``). Most strategies only need a different award order or plan
for the auction's batches: :class:`~btcap.team.allocation.strategies.BatchStrategy` with a
:class:`~btcap.team.core.turns.BatchPolicy`.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import ClassVar, Protocol

from btcap.actors import Actor
from btcap.team.core.auction import AuctionOutcome
from btcap.team.core.members import TeamEvent
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Bid, CallForBids, NoBid
from btcap.team.settings import MissionConfig

__all__ = [
    "Allocator",
    "AuctionRecord",
    "AuctionStats",
    "AuctionWatcher",
    "ConsensusStats",
    "Pricer",
    "RobotContext",
    "Strategy",
    "TeamView",
]


class TeamView(Protocol):
    """The robot's view of its team (its :class:`~btcap.team.membership.membership.Membership`)."""

    def alive(self) -> frozenset[str]: ...

    def suspected(self) -> frozenset[str]:
        """Members under suspicion of failure: no auction waits for their answer."""
        ...

    def subscribe(self, listener: Callable[[TeamEvent, str], None]) -> Callable[[], None]: ...


class Pricer(Protocol):
    """What this robot would bid (its :class:`~btcap.team.runtime.executor.ExecutorSide`)."""

    def evaluate(self, cfb: CallForBids) -> Bid | NoBid: ...

    @property
    def idle(self) -> bool: ...

    def claimed(self, execution: ExecutionId) -> None:
        """This robot claimed ``execution`` (consensus): its origin's award is expected."""


@dataclass(frozen=True, slots=True)
class RobotContext:
    """What a strategy is told once per robot, to make that robot's allocator."""

    robot: str
    settings: MissionConfig
    team: TeamView
    pricer: Pricer


@dataclass(frozen=True, slots=True)
class AuctionRecord:
    """An auction as a watcher sees it: reported once when it opens (``outcome`` and
    ``result`` None) and once when it ends (both set, or ``outcome`` None if it was
    cancelled while open)."""

    id: AuctionId
    task: AssignmentTask
    opened: float
    closed: float | None = None
    outcome: AuctionOutcome | None = None
    result: Assigned | Unassigned | None = None
    #: Why robots were passed over, winner or not: declined to bid, no answer, a bid not
    #: below the reserve, the award declined or unanswered.
    passed: Mapping[str, str] = dataclasses.field(default_factory=dict)


#: Called with every :class:`AuctionRecord` an allocator reports.
AuctionWatcher = Callable[[AuctionRecord], None]


@dataclass(slots=True)
class AuctionStats:
    auctions: int = 0
    awarded: int = 0
    unassigned: int = 0
    declined_awards: int = 0
    early_closes: int = 0


@dataclass(slots=True)
class ConsensusStats(AuctionStats):
    """The consensus strategy's (:mod:`~btcap.team.allocation.consensus`): ``auctions``:
    tasks offered; ``early_closes``: awarded on agreement, not the window; ``messages``:
    consensus messages sent (offers, claims and prices)."""

    messages: int = 0  #: consensus messages sent
    refused: int = 0  #: messages speaking for another robot, or with an impossible cost
    dropped: int = 0  #: tasks and view entries over the bounds a peer sent


class Allocator(Actor, abc.ABC):
    """One robot's part of a strategy: an actor at :attr:`PATH`, asked by mission
    control to place each task. Peers' messages to it are bounded by the allocator
    itself (a peer may send anything); awards go through the robots' mission control."""

    #: Where it is spawned on every robot (its peers address it there).
    PATH: ClassVar[str]
    #: Whether it passes an exchange (``AssignmentTask.handing``) on to the bidders, so
    #: re-evaluation may exchange running work between two busy robots through it.
    exchanges: ClassVar[bool] = False
    stats: AuctionStats

    @abc.abstractmethod
    async def assign(self, task: AssignmentTask) -> Assigned | Unassigned:
        """Find a robot that accepted to run ``task`` now, or say why none did."""

    @abc.abstractmethod
    def watch(self, watcher: AuctionWatcher) -> Callable[[], None]:
        """Report every allocation to ``watcher`` as it opens and ends; an unsubscribe."""


class Strategy(Protocol):
    """An allocation strategy: registered by ``name``, one allocator per robot.

    A strategy may also name in ``modules`` (absent: none) the heavy modules it imports
    only when it first needs them (numpy, scipy: a second of CPU): the robot imports them
    in a worker thread when it first attaches a mission, so that import never holds its
    event loop (see :class:`~btcap.team.runtime.agent.Agent`). Its work on the loop must
    stay short (~50 ms at most per callback): CPU-heavy steps run in a worker thread.
    """

    @property
    def name(self) -> str: ...

    def allocator(self, robot: RobotContext) -> Allocator: ...
