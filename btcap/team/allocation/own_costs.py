"""What a robot's own tasks cost it, for consensus allocation: priced by its executor
side as a call for bids would be, and cached while its body's state and the task stay
the same (a robot re-prices only when something it depends on changed)."""

from __future__ import annotations

from collections.abc import Mapping

from btcap.team.allocation.strategy import Pricer
from btcap.team.core.market import Task
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Bid, CallForBids, OpenTask

__all__ = ["OwnCosts"]


class OwnCosts:
    """``robot``'s costs through ``pricer`` (None: it can take nothing)."""

    def __init__(self, robot: str, pricer: Pricer | None) -> None:
        self.robot = robot
        self.pricer = pricer
        self._cache: dict[ExecutionId, tuple[OpenTask, Bid | str]] = {}
        self._idle: bool | None = None  # the body's state the prices were made in

    def clear(self) -> None:
        """Price everything again (preconditions may be met now)."""
        self._cache.clear()

    def costs(self, tasks: Mapping[ExecutionId, Task[OpenTask]]) -> dict[ExecutionId, float]:
        """The cost of each of ``tasks`` this robot may take; a holder's counts ``margin``
        lower."""
        pricer = self.pricer
        if pricer is None:
            return {}
        idle = pricer.idle
        if idle != self._idle:
            self._cache.clear()
            self._idle = idle
        for gone in self._cache.keys() - tasks.keys():
            del self._cache[gone]
        costs: dict[ExecutionId, float] = {}
        for execution, task in tasks.items():
            if self.robot not in task.candidates:
                continue
            spec = task.spec
            cached = self._cache.get(execution)
            if cached is None or cached[0] is not spec:
                cfb = CallForBids(
                    AuctionId(execution.origin, 0, execution.incarnation),
                    spec.interface,
                    spec.identity,
                    spec.inputs,
                    spec.holder,
                    speedup=spec.speedup,
                )
                got = pricer.evaluate(cfb)
                cached = (spec, got if isinstance(got, Bid) else got.reason)
                self._cache[execution] = cached
            bid = cached[1]
            if isinstance(bid, Bid):
                held = spec.holder_robot == self.robot
                costs[execution] = bid.cost * (1.0 - spec.margin) if held else bid.cost
        return costs

    def why(self, origin: str) -> list[tuple[ExecutionId, str]]:
        """``origin``'s tasks this robot cannot bid for, and why."""
        return [
            (t, answer)
            for t, (_spec, answer) in self._cache.items()
            if isinstance(answer, str) and t.origin == origin
        ]

    def implementation(self, task: ExecutionId) -> str:
        """The implementation this robot would run ``task`` with ("" if none)."""
        cached = self._cache.get(task)
        return cached[1].implementation if cached and isinstance(cached[1], Bid) else ""
