"""Allocation strategies by name: the five built-ins and the ``btcap.strategies`` entry
points of installed packages (see :mod:`btcap.team.allocation.strategy` for the protocol).

A package adds a strategy by declaring it in its ``pyproject.toml``::

    [project.entry-points."btcap.strategies"]
    random = "my_package.alloc:RANDOM"

where the value is a :class:`~btcap.team.allocation.strategy.Strategy` object, or a class or
function that makes one without arguments. Entry points are read when a name that is
not a built-in is asked for (a built-in never loads plug-ins), so agents start fast.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from importlib import metadata

from btcap.team.allocation.auction import SingleItemAuction
from btcap.team.allocation.consensus import ConsensusAssigner
from btcap.team.allocation.strategy import Allocator, RobotContext, Strategy
from btcap.team.core.turns import ARRIVAL, AUCTION, OPTIMAL, SEQUENTIAL, BatchPolicy

__all__ = [
    "BUILTIN",
    "ENTRY_POINT_GROUP",
    "BatchStrategy",
    "ConsensusStrategy",
    "check_strategy",
    "get",
    "names",
    "resolve",
]

#: The entry-point group third-party strategies are registered in.
ENTRY_POINT_GROUP = "btcap.strategies"


@dataclass(frozen=True, slots=True)
class BatchStrategy:
    """A strategy of the single-item auction: each robot's auctioneer collects bids for
    every task and awards the batches of concurrent auctions as ``policy`` says (which
    robot gets what, and in which order); the award step and its bounds are the
    auction's. The way to write most strategies."""

    name: str
    policy: BatchPolicy

    @property
    def modules(self) -> tuple[str, ...]:
        """What the policy imports when it first plans (a robot imports them in a worker
        thread when it first attaches a mission)."""
        return tuple(getattr(self.policy, "modules", ()))

    def allocator(self, robot: RobotContext) -> Allocator:
        s = robot.settings
        return SingleItemAuction(
            robot.robot,
            window_s=s.auction_window_s,
            award_timeout_s=s.award_timeout_s,
            policy=self.policy,
            team=robot.team,
        )


@dataclass(frozen=True, slots=True)
class ConsensusStrategy:
    """``consensus``: no auctioneer; every robot bids for its own task (the auction
    algorithm run by the robots), see
    :mod:`btcap.team.allocation.consensus`."""

    name: str = "consensus"

    def allocator(self, robot: RobotContext) -> Allocator:
        s = robot.settings
        return ConsensusAssigner(
            robot.robot,
            window_s=s.auction_window_s,
            award_timeout_s=s.award_timeout_s,
            team=robot.team,
            pricer=robot.pricer,
        )


#: The built-in strategies, in the order they are listed (see
#: :mod:`btcap.team.core.planning` for when to use which).
BUILTIN: Mapping[str, Strategy] = {
    "auction": BatchStrategy("auction", AUCTION),
    "sequential": BatchStrategy("sequential", SEQUENTIAL),
    "optimal": BatchStrategy("optimal", OPTIMAL),
    "arrival": BatchStrategy("arrival", ARRIVAL),
    "consensus": ConsensusStrategy(),
}


def _plugins() -> dict[str, metadata.EntryPoint]:
    eps = metadata.entry_points(group=ENTRY_POINT_GROUP)
    return {ep.name: ep for ep in sorted(eps, key=lambda e: e.name) if ep.name not in BUILTIN}


def names() -> list[str]:
    """Every strategy name: the built-ins, then the installed plug-ins, sorted."""
    return [*BUILTIN, *_plugins()]


def _expected() -> str:
    return f"expected one of {', '.join(names())}"


def check_strategy(name: str) -> str:
    """``name`` if a strategy has it; else a ValueError listing the valid names."""
    if name not in BUILTIN and name not in _plugins():
        raise ValueError(f"allocation strategy {name!r}: {_expected()}")
    return name


def get(name: str) -> Strategy:
    """The strategy called ``name``, loading its entry point if it is a plug-in."""
    if (builtin := BUILTIN.get(name)) is not None:
        return builtin
    ep = _plugins().get(name)
    if ep is None:
        raise ValueError(f"allocation strategy {name!r}: {_expected()}")
    try:
        made = _made(ep.load())
    except Exception as exc:
        raise ValueError(
            f"allocation strategy {name!r}: entry point {ep.value!r} failed to load: "
            f"{type(exc).__name__}: {exc}"
        ) from exc
    if made is None:
        raise ValueError(
            f"allocation strategy {name!r}: entry point {ep.value!r} is not a strategy "
            "(an object with a name and an allocator(robot) method, or a factory of one)"
        )
    return made


def _made(value: object) -> Strategy | None:
    if not isinstance(value, type) and _is_strategy(value):
        return value  # type: ignore[return-value]
    if callable(value):
        made: object = value()
        return made if _is_strategy(made) else None  # type: ignore[return-value]
    return None


def _is_strategy(value: object) -> bool:
    return isinstance(getattr(value, "name", None), str) and callable(
        getattr(value, "allocator", None)
    )


def resolve(strategy: str | Strategy) -> Strategy:
    """A strategy given by name or as an object."""
    return get(strategy) if isinstance(strategy, str) else strategy
