"""Messages of the capability layer: team membership, repository gossip, auctions,
executions.

Every type here is registered by :func:`btcap.team.runtime.protocol.protocol_registry`,
so it travels between robots over any transport. Values of capability ports travel as
``Any`` and are converted back to their declared types on arrival. The consensus
allocation's messages (:mod:`btcap.team.consensus_messages`) and the observers'
(:mod:`btcap.team.observing`) live in modules of their own and are named here too."""

from __future__ import annotations

import enum
from typing import Any

import msgspec

from btcap.team.consensus_messages import (
    ConsensusClaim,
    ConsensusPrices,
    ConsensusTasks,
    OpenTask,
)
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.observing import (
    Departed,
    Departures,
    DeparturesQuery,
    Seen,
    StatusQuery,
    TeamStatus,
)
from btcap.transports.message import Message

__all__ = [
    "CAPABILITY_MESSAGES",
    "RUN_DONE",
    "Activity",
    "ActivityQuery",
    "Award",
    "AwardReply",
    "Bid",
    "CallForBids",
    "CancelExecution",
    "ConsensusClaim",
    "ConsensusPrices",
    "ConsensusTasks",
    "Contact",
    "CostChanged",
    "Departed",
    "Departures",
    "DeparturesQuery",
    "ExecutionInputs",
    "ExecutionStatus",
    "Goodbye",
    "Heard",
    "Heartbeat",
    "KeepAlive",
    "NoBid",
    "OpenTask",
    "PauseExecution",
    "ProbeRequest",
    "RepositoryQuery",
    "RepositoryState",
    "Roster",
    "RosterRequest",
    "RunState",
    "Seen",
    "StatusQuery",
    "TeamStatus",
    "Vouch",
]


# -- team --------------------------------------------------------------------------------
class Heard(msgspec.Struct, frozen=True, array_like=True):
    """News of a teammate passed on by gossip: alive at ``beat`` (a join, or a refutation
    of a suspicion), or, ``suspect``, suspected of having failed at ``beat`` (first by
    ``by``). ``age_ms`` is kept for old peers and is 0 in news btcap sends now."""

    robot: str
    incarnation: int
    beat: int
    age_ms: int = 0
    #: ``by`` suspects ``robot`` of having failed at ``beat`` (see :mod:`btcap.team.core.swim`).
    suspect: bool = False
    by: str = ""


class Heartbeat(Message):
    """I am alive; ``incarnation`` changes when a robot restarts, ``repo_version`` when its
    capabilities change (peers then ask for the new :class:`RepositoryState`); ``busy``
    says whether its body is taken (a robot coming free is news for waiting work).
    ``beat`` is the version of what a robot says of itself within one life: it grows when
    the robot refutes a suspicion or its ``busy``/``repo_version`` change; ``heard`` is news
    of teammates (joins, suspicions, refutations) passed on by gossip (see
    :mod:`btcap.team.core.swim`)."""

    robot: str
    incarnation: int
    repo_version: int
    busy: bool = False
    beat: int = 0
    heard: list[Heard] = []
    #: Non-zero: a probe; answer at once with a heartbeat whose ``ack`` is this number.
    probe: int = 0
    #: Non-zero: the answer to the sender's probe of that number.
    ack: int = 0


class Contact(msgspec.Struct, frozen=True, array_like=True):
    """Where a teammate can be reached."""

    robot: str
    endpoint: str


class Roster(Message):
    """Teammates and where to reach them: sent to a robot that just joined, or that asked
    (:class:`RosterRequest`) about robots it heard of but cannot reach."""

    contacts: list[Contact]


class RosterRequest(Message):
    """Where can I reach these robots (that your heartbeats mention)?"""

    robots: list[str]


class ActivityQuery(Message):
    """What are you running? (asked by ``btcap team status``)"""


class Activity(Message):
    """The executions a robot's body runs and holds queued, its own and its teammates'."""

    robot: str
    running: list[ExecutionId]
    queued: list[ExecutionId] = []


class Goodbye(Message):
    """I am leaving the team on purpose."""

    robot: str
    incarnation: int


class ProbeRequest(Message):
    """My probe ``probe`` of ``target`` went unanswered: probe it for me (SWIM's
    indirect probe, through a path that may not share my lossy link)."""

    target: str
    probe: int


class Vouch(Message):
    """``target`` answered the probe you asked me for (``probe`` is your number): I, the
    sender, heard it myself, in its life ``incarnation`` at ``beat``. With ``answered``
    false it is Lifeguard's nack, sent as soon as I was asked: I am here and trying, so
    if the target stays silent the fault is not your own network."""

    target: str
    probe: int
    incarnation: int
    beat: int
    answered: bool = True


# -- repository --------------------------------------------------------------------------
class RepositoryState(Message):
    """A robot's implemented interfaces (by identity) and the capabilities it completed."""

    robot: str
    version: int
    interfaces: dict[str, str]
    succeeded: list[str] = []


class RepositoryQuery(Message):
    """Ask a robot's repository for its full state (after a missed update)."""

    robot: str


# -- auctions ----------------------------------------------------------------------------
class CallForBids(Message):
    """Who can run ``interface`` with these inputs, and at what cost? Answers go to the
    auctioneer named in the auction's id. ``holder``: running work is re-evaluated, and
    the robot running execution ``holder`` bids what finishing it there would cost.
    ``handing``: an exchange; the robot running ``handing`` bids as if it handed that over
    (no wait), and may be awarded this task beside it. ``extended``: a time-extended call;
    a robot too busy to take the task still says what it would cost it after the work it
    holds (a :class:`Bid` with ``after``), so the planner knows what waiting costs."""

    auction: AuctionId
    interface: str
    identity: str
    inputs: dict[str, Any]
    holder: ExecutionId | None = None
    handing: ExecutionId | None = None
    extended: bool = False
    #: The auctioneer's clock speed-up (0: a virtual clock, or not said): a robot whose
    #: clock runs at another rate does not bid (see :class:`Award`).
    speedup: float = 0.0


class Bid(Message):
    """A cost (lower is better) for running the capability with one implementation.

    ``after``: the work the robot must finish first, included in ``cost`` (a busy robot
    that may queue the task, or one bidding for later). ``later``: a time-extended bid
    (see :attr:`CallForBids.extended`): the robot is too busy to take the task and says
    what it would cost it once its work is done, so a planner knows what waiting costs;
    never awarded."""

    auction: AuctionId
    robot: str
    cost: float
    implementation: str
    after: float = 0.0
    later: bool = False


class NoBid(Message):
    """A decline, so the auction can close before its window ends."""

    auction: AuctionId
    robot: str
    reason: str


class Award(Message):
    """You won: take ``implementation`` as execution ``execution``; it starts with the
    origin's first renewal (or, ``paused``, with its first inputs: work being moved must
    not run twice). The run is the origin's, named in ``execution``; the executor stops it
    ``lease_s`` x 0.9 after the newest of its stamps the origin echoed (before the origin
    may re-assign it: :mod:`btcap.team.core.fence`)."""

    auction: AuctionId
    execution: ExecutionId
    interface: str
    implementation: str
    inputs: dict[str, Any]
    lease_s: float
    paused: bool = False
    #: An exchange: the winner holds this (paused) beside ``handing``, which it runs and
    #: hands over; it starts when ``handing`` is released.
    handing: ExecutionId | None = None
    #: The origin's clock speed-up (clock seconds per wall second; 0: a virtual clock, or
    #: not said): leases are clock seconds, so a winner whose clock runs at another rate
    #: declines (its run could act after the origin gave it up).
    speedup: float = 0.0


class AwardReply(Message):
    """Whether the winner took the award (it may have become busy since it bid)."""

    execution: ExecutionId
    robot: str
    accepted: bool
    reason: str = ""
    #: The winner's clock as it accepted: the origin echoes it to start the run.
    stamp: float | None = None


# -- executions --------------------------------------------------------------------------
class RunState(enum.Enum):
    """The state of a remote execution, as its executor reports it.

    The team's own states, kept apart from the node states of :class:`~btcap.bt.state.State`
    so the core needs no behaviour tree; the values are the node states' (the executor
    reports its implementation's root state), so the wire bytes are the same. LOST is what
    an executor reports for an execution it does not (or no longer) have; its wire value is
    ``"shutdown"``.
    """

    UNINITIALIZED = "uninitialized"
    IDLE = "idle"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    ERROR = "error"
    LOST = "shutdown"
    PAUSED = "paused"
    UNASSIGNED = "unassigned"
    ASSIGNED = "assigned"


#: Run states that end an execution with a result.
RUN_DONE = frozenset({RunState.SUCCEEDED, RunState.FAILED, RunState.ERROR})


class ExecutionInputs(Message):
    """The capability's latest inputs, sent every tick of the capability node."""

    execution: ExecutionId
    seq: int
    inputs: dict[str, Any]
    #: The executor's newest stamp the origin heard: renews the run's lease (None: not).
    echo: float | None = None


class ExecutionStatus(Message):
    """The implementation's root state and outputs, sent back every tick of the slot."""

    execution: ExecutionId
    robot: str
    state: RunState
    outputs: dict[str, Any]
    seq: int = 0
    detail: str = ""
    #: The executor's clock as it sent this (the origin echoes it in its renewals).
    stamp: float | None = None


class PauseExecution(Message):
    """The capability node was unticked: pause the implementation, keep it."""

    execution: ExecutionId


class CancelExecution(Message):
    """The capability node was reset or shut down: stop and remove the implementation."""

    execution: ExecutionId
    reason: str = ""


class KeepAlive(Message):
    """Renews the leases of these executions (sent while no tick traffic flows). Each
    execution has its stamp at the same index of ``stamps``: for one the sender runs, its
    clock now; for one it is the origin of, the receiver's newest stamp it heard (the
    echo that renews the run: :mod:`btcap.team.core.fence`)."""

    robot: str
    executions: list[ExecutionId]
    stamps: list[float] = []


class CostChanged(Message):
    """The executor's own estimate of finishing this execution rose beyond the margin:
    its origin re-evaluates the running work now (see :mod:`btcap.team.core.costwatch`)."""

    execution: ExecutionId
    cost: float


CAPABILITY_MESSAGES: tuple[type[Message], ...] = (
    Heartbeat,
    Goodbye,
    Roster,
    RosterRequest,
    ActivityQuery,
    Activity,
    RepositoryState,
    RepositoryQuery,
    CallForBids,
    Bid,
    NoBid,
    Award,
    AwardReply,
    ConsensusTasks,
    ConsensusClaim,
    ConsensusPrices,
    ExecutionInputs,
    ExecutionStatus,
    PauseExecution,
    CancelExecution,
    KeepAlive,
    CostChanged,
    StatusQuery,
    TeamStatus,
    DeparturesQuery,
    Departures,
    ProbeRequest,
    Vouch,
)
