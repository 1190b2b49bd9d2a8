"""Exchanges of running work between busy robots: which to make, and in what order.

Re-evaluation (:mod:`btcap.team.runtime.moving`) moves running work only to free robots.
Two busy robots can still be a bad pair, each driving to the other's goal: neither bids
for the other's task (a busy robot answers "busy"), so nothing moves. An *exchange* gives
each of a cycle of running tasks to the next task's robot (two tasks: a swap; three: a
short chain), priced by what each robot says a task would cost it *if it handed its
current one over* (from where it is now, no wait) and by what finishing its current one
costs it (the estimate it already re-reports for cost news). It is made only when the
cycle's total falls by more than ``margin`` of what the cycle costs now, the same
hysteresis as moving work to a free robot, so near-equal pairs never trade back and
forth.

Executing one is a two-phase hand-over (:class:`Handover`), so no task runs twice and
none is dropped: every leg's new run is first *reserved* (its target accepts it paused,
beside the run it is handing over); only when every leg is reserved are they *committed*
(each node adopts its replacement, which cancels the old run, as a move to a free robot
does). A leg declined, lost or not answered before the deadline aborts the whole
exchange: the reserved paused runs are cancelled and every task stays where it was. A
paused run never starts without its node's inputs, and its lease lapses with its origin,
so an origin that dies mid-exchange leaves nothing running twice.

Sans-IO: decided on explicit costs and explicit time; the shell asks for the costs and
sends the awards.
"""

from __future__ import annotations

import enum
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from btcap.team.ids import ExecutionId

__all__ = ["Exchange", "Handover", "Leg", "Phase", "Running", "find_exchanges", "pays"]


@dataclass(frozen=True, slots=True)
class Running:
    """One running task, its robot and what finishing it there costs now."""

    execution: ExecutionId
    robot: str
    cost: float


@dataclass(frozen=True, slots=True)
class Leg:
    """Task ``execution`` goes from ``frm`` to ``to``, where it costs ``cost``."""

    execution: ExecutionId
    frm: str
    to: str
    cost: float


@dataclass(frozen=True, slots=True)
class Exchange:
    """A cycle of hand-overs; ``before``/``after``: the cycle's total cost."""

    legs: tuple[Leg, ...]
    before: float
    after: float

    @property
    def gain(self) -> float:
        return self.before - self.after


Cross = Mapping[tuple[str, ExecutionId], float]


def pays(before: float, after: float, margin: float) -> bool:
    """Whether a cycle costing ``before`` now and ``after`` exchanged is worth the switch:
    the total falls by more than ``margin`` of ``before``."""
    return math.isfinite(before) and after < before * (1.0 - margin) - 1e-9


def _cycle(cycle: Sequence[Running], cross: Cross, margin: float) -> Exchange | None:
    """Each task of ``cycle`` goes to the next one's robot; None unless all can take theirs
    and the total falls by more than ``margin`` of the cycle's current total."""
    legs: list[Leg] = []
    for i, task in enumerate(cycle):
        to = cycle[(i + 1) % len(cycle)].robot
        cost = cross.get((to, task.execution))
        if cost is None or not math.isfinite(cost):
            return None
        legs.append(Leg(task.execution, task.robot, to, cost))
    before = sum(t.cost for t in cycle)
    after = sum(leg.cost for leg in legs)
    if not pays(before, after, margin):
        return None
    return Exchange(tuple(legs), before, after)


def find_exchanges(
    running: Sequence[Running], cross: Cross, margin: float, *, chain: int = 3
) -> list[Exchange]:
    """Disjoint exchanges that lower the team's total cost, the largest gain first.

    ``cross[(robot, execution)]``: what ``execution`` would cost ``robot`` if it handed its
    own running task over (missing: it cannot take it). Cycles of two tasks (swaps) and,
    with ``chain`` 3, of three (both rotations). At most one task per robot is considered
    (a robot with two running tasks is not a candidate). Ties go to the cycle whose
    executions sort first, so the same inputs always give the same exchanges.
    """
    if margin < 0:
        raise ValueError(f"exchange margin {margin}: expected at least 0")
    if chain not in (2, 3):
        raise ValueError(f"exchange chain {chain}: expected 2 or 3")
    per_robot: dict[str, list[Running]] = {}
    for task in running:
        per_robot.setdefault(task.robot, []).append(task)
    tasks = sorted(
        (ts[0] for ts in per_robot.values() if len(ts) == 1), key=lambda t: str(t.execution)
    )
    found: list[tuple[float, list[str], Exchange]] = []
    for size in range(2, chain + 1):
        for group in itertools.combinations(tasks, size):
            orders = [group] if size == 2 else [group, (group[0], group[2], group[1])]
            for order in orders:
                ex = _cycle(order, cross, margin)
                if ex is not None:
                    found.append((-ex.gain, [str(t.execution) for t in order], ex))
    found.sort(key=lambda f: (f[0], f[1]))
    chosen: list[Exchange] = []
    busy: set[str] = set()
    for _gain, _key, ex in found:
        robots = {leg.frm for leg in ex.legs}
        if robots & busy:
            continue
        busy |= robots
        chosen.append(ex)
    return chosen


class Phase(enum.Enum):
    RESERVING = "reserving"
    COMMITTED = "committed"
    ABORTED = "aborted"


@dataclass(slots=True)
class Handover:
    """The two-phase hand-over of one exchange, decided on explicit time.

    The shell awards every leg paused (its target keeps running the task it hands over)
    and reports each answer here. :meth:`commit` says when every leg is reserved: then,
    and only then, each node may adopt its replacement. :meth:`abort` lists the reserved
    legs whose paused runs must be cancelled.
    """

    exchange: Exchange
    deadline: float
    phase: Phase = Phase.RESERVING
    reserved: set[ExecutionId] = field(default_factory=set)
    why: str = ""

    def accepted(self, execution: ExecutionId) -> None:
        """``execution``'s new run was accepted, paused, by its leg's target."""
        if self.phase is Phase.RESERVING and self._leg(execution) is not None:
            self.reserved.add(execution)

    def declined(self, execution: ExecutionId, why: str) -> list[Leg]:
        """A leg could not be reserved (declined, lost, or its task ended or moved): the
        exchange is off; returns the reserved legs to cancel."""
        if self.phase is not Phase.RESERVING or self._leg(execution) is None:
            return []
        return self._abort(f"{execution}: {why}")

    def tick(self, now: float) -> list[Leg]:
        """Past the deadline with a leg unanswered: the exchange is off (as declined)."""
        if self.phase is Phase.RESERVING and now >= self.deadline and not self.ready:
            return self._abort("not every leg reserved in time")
        return []

    @property
    def ready(self) -> bool:
        return all(leg.execution in self.reserved for leg in self.exchange.legs)

    def commit(self) -> list[Leg]:
        """Every leg reserved: the legs whose nodes adopt their replacements now (each
        adoption cancels the old run). Nothing before that."""
        if self.phase is not Phase.RESERVING or not self.ready:
            return []
        self.phase = Phase.COMMITTED
        return list(self.exchange.legs)

    def _abort(self, why: str) -> list[Leg]:
        self.phase = Phase.ABORTED
        self.why = why
        cancel = [leg for leg in self.exchange.legs if leg.execution in self.reserved]
        self.reserved.clear()
        return cancel

    def _leg(self, execution: ExecutionId) -> Leg | None:
        return next((leg for leg in self.exchange.legs if leg.execution == execution), None)
