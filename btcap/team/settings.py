"""A robot's team and allocation settings: one msgspec schema for code, agent files and
scenario files alike, so each setting's type, bounds, meaning and default, and each check
between settings, exist once.

- :class:`Timing` and :class:`Allocation` are the ``timing:``/``agent:`` and
  ``allocation:`` blocks of the files (an agent file adds the clock's speed-up, a scenario
  re-declares the timing defaults in simulated seconds); the file reference is generated
  from them.
- :class:`MissionConfig` and :class:`AgentConfig` are what code builds: flat, the same
  fields under the same names, defaults taken from the blocks (msgspec Structs cannot
  inherit from two Structs with fields, hence the names are repeated; a test checks they
  match). Both blocks give an :class:`AgentConfig` with :meth:`AgentConfig.of`.

msgspec checks a field's bounds only when it decodes; ``__post_init__`` runs on decode
and on ``__init__`` alike, so settings built in Python are checked there as files are:
bounds and relations (``failure_timeout_s > heartbeat_s``, ``keepalive_s < lease_s``), a
``ValueError`` naming the field. The strategy is a name, checked against the known
strategies where an allocator is built (and by the file loaders), not here.
"""

from __future__ import annotations

from contextvars import ContextVar
from typing import Annotated, Any

import msgspec

from btcap.team.filecheck import field_first

__all__ = [
    "AgentConfig",
    "Allocation",
    "AuctionWindowS",
    "AwardTimeoutS",
    "FailureTimeoutS",
    "HeartbeatFanout",
    "HeartbeatS",
    "HoldDownS",
    "KeepaliveS",
    "LeaseS",
    "MaxLeaseS",
    "MissionConfig",
    "MoveMargin",
    "QueueAfterCurrent",
    "RebidOnJoin",
    "ReevaluateS",
    "StrategyName",
    "TickHz",
    "Timing",
    "check_heartbeat",
    "check_lease",
    "check_max_lease",
]


def _doc(text: str) -> msgspec.Meta:
    return msgspec.Meta(description=text)


def _seconds(text: str) -> msgspec.Meta:
    return msgspec.Meta(gt=0, description=f"{text} (clock seconds).")


# Each setting's type, bounds and meaning, used by every Struct that has the setting.
TickHz = Annotated[
    float, msgspec.Meta(gt=0, description="How often the robot's own tree is ticked (Hz).")
]
HeartbeatS = Annotated[
    float, _seconds("The failure detector's period: the robot probes one teammate this often")
]
FailureTimeoutS = Annotated[
    float,
    _seconds(
        "The shortest time a suspected teammate has to refute before it is failed; the "
        "suspicion timeout scales with the team above it (docs/membership.md); more than "
        "`heartbeat_s`"
    ),
]
HeartbeatFanout = Annotated[
    int,
    msgspec.Meta(
        ge=1,
        description="News items (joins, suspicions, refutations) per membership message; "
        "also how many peers that are no members get a heartbeat per period.",
    ),
]
LeaseS = Annotated[
    float,
    _seconds(
        "How long an execution lives without word from the other side: the executor stops "
        "its run 0.9 times this after the newest of its stamps the origin echoed, and the "
        "origin starts the task elsewhere only this long after that stamp arrived; "
        "`keepalive_s` and the origin's tick period must stay well under 0.9 times this"
    ),
]
KeepaliveS = Annotated[
    float, _seconds("How often the origin renews a running execution; less than `lease_s`")
]
AuctionWindowS = Annotated[
    float,
    _seconds(
        "An auction closes after this long, or earlier once every live, eligible teammate "
        "has bid or declined"
    ),
]
AwardTimeoutS = Annotated[
    float,
    _seconds("How long an auctioneer waits for the winner to accept, before the next bidder"),
]
ReevaluateS = Annotated[
    Annotated[float, msgspec.Meta(gt=0)] | None,
    _doc(
        "Re-evaluate running work this often (clock seconds) and whenever the team changes "
        "(a robot joins, comes free or changes); null: running work never moves."
    ),
]
MoveMargin = Annotated[
    float,
    msgspec.Meta(
        ge=0,
        lt=1,
        description="Work moves only to a robot bidding at least this fraction below what "
        "its current executor now bids to finish it (0.2: a fifth cheaper), which covers the "
        "cost of switching and keeps near-equal robots from passing work back and forth.",
    ),
]
StrategyName = Annotated[
    str,
    msgspec.Meta(
        min_length=1,
        description="How auctions competing for the same robots are awarded: `optimal` (the "
        "default: least total cost), `auction` (the paper's: each to its cheapest free "
        "bidder, by regret), `sequential` (a greedy plan improved by exchanges and chains), "
        "`arrival` (each as it closes), "
        "`consensus` (decentralised, no auctioneer), or the name of an installed "
        "`btcap.strategies` plug-in.",
    ),
]
RebidOnJoin = Annotated[
    Annotated[float, msgspec.Meta(gt=0, lt=1)] | None,
    _doc("Older name of `move_margin` for joins; null: `move_margin`."),
]
QueueAfterCurrent = Annotated[
    bool,
    _doc(
        "A busy robot also bids for one more task, to start after its current one, at its "
        "current bid plus the new one; false: a busy robot declines to bid."
    ),
]


MaxLeaseS = Annotated[
    float,
    _seconds(
        "The longest lease this robot accepts in an award: a member that stops renewing "
        "its run holds the robot at most this long; not below `lease_s`"
    ),
]


def check_heartbeat(heartbeat_s: float, failure_timeout_s: float) -> None:
    """A suspected teammate must get at least a period to refute before it is failed."""
    if failure_timeout_s <= heartbeat_s:
        raise ValueError("failure_timeout_s: must exceed heartbeat_s")


def check_lease(lease_s: float, keepalive_s: float) -> None:
    """A running execution must be renewed before its lease runs out."""
    if keepalive_s >= lease_s:
        raise ValueError("keepalive_s: must be below lease_s")


def check_max_lease(lease_s: float, max_lease_s: float) -> None:
    """The team's own awards (with this file's ``lease_s``) must be accepted."""
    if max_lease_s < lease_s:
        raise ValueError("max_lease_s: must not be below lease_s")


#: Set while :func:`_check_bounds` converts, so the copy it makes is not checked again.
_CONVERTING: ContextVar[bool] = ContextVar("btcap_settings_converting", default=False)


def _check_bounds(settings: msgspec.Struct) -> None:
    """The bounds of the field types, as decoding checks them (msgspec does not on
    ``__init__``): ValueError ``"lease_s: Expected `float` > 0.0"``."""
    if _CONVERTING.get():
        return
    token = _CONVERTING.set(True)
    try:
        msgspec.convert(msgspec.structs.asdict(settings), type(settings))
    except msgspec.ValidationError as exc:
        raise ValueError(field_first(str(exc))) from None
    finally:
        _CONVERTING.reset(token)


HoldDownS = Annotated[
    float,
    msgspec.Meta(
        ge=0,
        description="A task moved or exchanged to another robot is not handed back to the "
        "robot it left within this many clock seconds, whatever the bids say then (a robot "
        "that frees soon would otherwise take back work it just gave away); 0: no hold-down.",
    ),
]


class Timing(msgspec.Struct, kw_only=True, forbid_unknown_fields=True, frozen=True):
    """Rates and timeouts of the protocol, in clock seconds."""

    tick_hz: TickHz = 10.0
    heartbeat_s: HeartbeatS = 0.1
    failure_timeout_s: FailureTimeoutS = 0.5
    heartbeat_fanout: HeartbeatFanout = 8
    lease_s: LeaseS = 0.8
    keepalive_s: KeepaliveS = 0.2
    auction_window_s: AuctionWindowS = 1.0
    award_timeout_s: AwardTimeoutS = 0.5

    def __post_init__(self) -> None:
        _check_bounds(self)
        check_heartbeat(self.heartbeat_s, self.failure_timeout_s)
        check_lease(self.lease_s, self.keepalive_s)


class Allocation(msgspec.Struct, kw_only=True, forbid_unknown_fields=True, frozen=True):
    """How work is allocated and moved: the policies of
    :class:`~btcap.team.settings.MissionConfig`."""

    reevaluate_s: ReevaluateS = 30.0
    move_margin: MoveMargin = 0.2
    strategy: StrategyName = "optimal"
    rebid_on_join: RebidOnJoin = None
    queue_after_current: QueueAfterCurrent = False
    max_lease_s: MaxLeaseS = 300.0
    hold_down_s: HoldDownS = 60.0

    def __post_init__(self) -> None:
        _check_bounds(self)


_T = Timing()
_A = Allocation()


class MissionConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """A robot's mission control: protocol timing in clock seconds, and the allocation
    policies (each field as in :class:`Timing` and :class:`Allocation`).

    Running work is re-evaluated every ``reevaluate_s`` and whenever the team changes: it
    moves to another robot only if that one bids at least ``move_margin`` below what the
    current executor now bids to finish it. ``strategy`` names how auctions competing for
    the same robots are awarded (see :mod:`btcap.team.allocation.strategies`).
    """

    lease_s: LeaseS = _T.lease_s
    keepalive_s: KeepaliveS = _T.keepalive_s
    auction_window_s: AuctionWindowS = _T.auction_window_s
    award_timeout_s: AwardTimeoutS = _T.award_timeout_s
    reevaluate_s: ReevaluateS = _A.reevaluate_s
    move_margin: MoveMargin = _A.move_margin
    strategy: StrategyName = _A.strategy
    rebid_on_join: RebidOnJoin = _A.rebid_on_join
    queue_after_current: QueueAfterCurrent = _A.queue_after_current
    max_lease_s: MaxLeaseS = _A.max_lease_s
    hold_down_s: HoldDownS = _A.hold_down_s

    def __post_init__(self) -> None:
        _check_bounds(self)
        check_lease(self.lease_s, self.keepalive_s)
        check_max_lease(self.lease_s, self.max_lease_s)


class AgentConfig(MissionConfig, kw_only=True):
    """Everything one robot is tuned by, in clock seconds: :class:`MissionConfig` plus the
    tree's tick rate and the membership's heartbeats."""

    tick_hz: TickHz = _T.tick_hz
    heartbeat_s: HeartbeatS = _T.heartbeat_s
    failure_timeout_s: FailureTimeoutS = _T.failure_timeout_s
    heartbeat_fanout: HeartbeatFanout = _T.heartbeat_fanout

    def __post_init__(self) -> None:
        super().__post_init__()
        check_heartbeat(self.heartbeat_s, self.failure_timeout_s)

    @classmethod
    def of(cls, timing: Timing, allocation: Allocation) -> AgentConfig:
        """The settings of a file's ``timing`` (or scenario's ``agent``) and ``allocation``
        blocks; a block's extra fields (the agent file's ``speedup``) are not settings."""
        values: dict[str, Any] = {
            **msgspec.structs.asdict(allocation),
            **msgspec.structs.asdict(timing),
        }
        return cls(**{name: values[name] for name in cls.__struct_fields__})
