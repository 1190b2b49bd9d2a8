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
forth, and when no robot handing its task over would take it back once free
(:func:`~btcap.team.core.handovers.comes_back`).

Re-evaluation carries out swaps and chains of three (``Reevaluation._cycle`` in
:mod:`btcap.team.runtime.moving`): each leg's new run is first accepted *paused* by its
target, beside the run it hands over; only when every leg is accepted and :func:`pays`
holds do the nodes adopt their replacements (each adoption cancels the old run, as a
move to a free robot does); otherwise every paused run is cancelled and every task
stays where it was. :func:`find_exchanges` chooses from full knowledge (the offline
estimate ``python -m btcap.bench.allocation.exchanges``); at run time the origin knows only what
bidders already said, kept in a :class:`Ledger`, which says which cycles are worth an
auction at all.

Sans-IO: decided on explicit costs; the shell asks for the costs and sends the awards.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass

from btcap.team.core.handovers import comes_back
from btcap.team.ids import ExecutionId

__all__ = ["Exchange", "Ledger", "Leg", "Running", "find_exchanges", "pays"]


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
    n = len(cycle)
    if any(comes_back(legs[i - 1].cost, cycle[i].cost, legs[i].cost, margin) for i in range(n)):
        return None  # a robot would take its task back once free: undone soon after
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


class Ledger:
    """What bidders already said about running work, so that exchanges which cannot pay
    are not auctioned again and again.

    ``held[x]``: the latest bid of ``x``'s robot for finishing ``x`` (a holder bids in
    every re-evaluation); ``cross[(y, x)]``: the bid of the robot running ``y`` for task
    ``x`` as if it handed ``y`` over (an exchange leg; infinite: it declined), with what
    finishing ``y`` cost that robot then. A cycle is worth trying only if it could pay
    by these bids (:meth:`may_pay`), each leg nobody bid for yet priced 0 and each leg
    bid for earlier lowered by the progress its robot made since (how much its own
    estimate fell): with bids that follow the robot (:mod:`btcap.team.core.body`) and
    costs that are paths, a robot that came ``d`` closer to its goal is at most ``d``
    closer to any other task. So a cycle whose gain was too small is asked again only
    once the margin's share of what is left has fallen below that gain, a bid rose (a
    blocked path), or its work changed (new executions, new keys).
    """

    __slots__ = ("cross", "held")

    def __init__(self) -> None:
        self.held: dict[ExecutionId, float] = {}
        self.cross: dict[tuple[ExecutionId, ExecutionId], tuple[float, float | None]] = {}

    def holder(self, execution: ExecutionId, cost: float) -> None:
        """``execution``'s robot says finishing it costs ``cost`` now."""
        self.held[execution] = cost

    def leg(self, handing: ExecutionId, execution: ExecutionId, cost: float | None) -> None:
        """The robot running ``handing`` bid ``cost`` for ``execution`` (None: declined)."""
        bid = math.inf if cost is None else cost
        self.cross[(handing, execution)] = (bid, self.held.get(handing))

    def keep(self, live: Collection[ExecutionId]) -> None:
        """Forget what was said about executions that ended or moved."""
        self.held = {x: c for x, c in self.held.items() if x in live}
        self.cross = {k: c for k, c in self.cross.items() if k[0] in live and k[1] in live}

    def cost(self, task: Running) -> float:
        """What finishing ``task`` costs its robot, as last heard."""
        return self.held.get(task.execution, task.cost)

    def leg_cost(self, handing: ExecutionId, execution: ExecutionId) -> float | None:
        """The least the robot running ``handing`` may bid for ``execution`` now, by what
        it said before (None: it was never asked)."""
        said = self.cross.get((handing, execution))
        if said is None:
            return None
        bid, then = said
        now = self.held.get(handing)
        progress = 0.0 if then is None or now is None else max(0.0, then - now)
        return max(0.0, bid - progress)

    def may_pay(self, cycle: Sequence[Running], margin: float) -> bool:
        """Whether ``cycle`` (each task to the next one's robot) could pay (see the class)."""
        before = sum(self.cost(t) for t in cycle)
        after = 0.0
        for i, t in enumerate(cycle):
            leg = self.leg_cost(cycle[(i + 1) % len(cycle)].execution, t.execution)
            after += 0.0 if leg is None else leg
        return pays(before, after, margin)

    def first_unknown(self, cycle: Sequence[Running]) -> tuple[Running, ...]:
        """``cycle`` rotated so that its first leg is one nobody bid for yet (that bid
        decides most often whether the rest is asked at all)."""
        n = len(cycle)
        for i in range(n):
            if (cycle[(i + 1) % n].execution, cycle[i].execution) not in self.cross:
                return tuple(cycle[i:]) + tuple(cycle[:i])
        return tuple(cycle)

    def cycles(
        self,
        running: Sequence[Running],
        margin: float,
        *,
        chain: int = 3,
        chain_of: int | None = None,
    ) -> Iterator[tuple[Running, ...]]:
        """Cycles worth an auction, in order: pairs, then (``chain`` 3) chains of three in
        both directions among the first ``chain_of`` tasks (all: None), each from
        ``running`` as given (the dearest first, say); each rotated by
        :meth:`first_unknown`. Lazy: the caller's answers to earlier cycles (new bids in
        the ledger) decide whether later ones are still worth it."""
        for size in range(2, chain + 1):
            pool = running if size == 2 or chain_of is None else running[:chain_of]
            for group in itertools.combinations(pool, size):
                orders = [group] if size == 2 else [group, (group[0], group[2], group[1])]
                for order in orders:
                    if self.may_pay(order, margin):
                        yield self.first_unknown(order)
