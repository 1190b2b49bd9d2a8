"""How closed auctions competing for the same robots are awarded: the order and, for the
planning strategies, who gets what.

The auctioneer holds every closed auction of a batch (the auctions that ran at the same
time for the same robots) until none still collecting bids competes for those robots, so
it sees the batch's full bid matrix. The strategies differ in what they do with it:

- ``optimal`` (the default): the batch's least total cost (the Hungarian method, scipy),
  with time-extended bids: busy robots say what each task would cost them later, and
  with more tasks than free robots the tasks that start are those for which waiting
  would cost most against starting now (without busy robots' bids: the cheapest set of
  tasks that can start together, the first wave); the others wait for the next robot
  that comes free, or are queued on a busy robot that is clearly their best. Chosen from
  ``python -m btcap.bench allocation`` (the best total cost at every size measured, at
  the same messages and CPU as the others; O(n^3), 6 ms for 100 x 100) and ``python -m
  btcap.bench missiontime`` (the only strategy near the offline reference).
- ``auction`` (the paper's single-item auction with re-auctions): each auction is
  awarded on its own, to its cheapest bidder still free; the order is by *regret* (the
  auction whose best free bid is furthest below its second-best goes first, one with a
  single bidder before all), so a task that would lose much by waiting is not beaten to
  its robot by one that has an almost-as-good alternative. No robot is ever given a task
  it did not bid cheapest for among the free ones; what a batch gets wrong,
  re-evaluation of running work (:mod:`btcap.team.runtime.moving`) improves later (about
  1.10x the optimum at 20 x 20, 1.4x for the first wave of 10 robots x 20 tasks).
- ``sequential`` (sequential single-item auctions over all pending tasks, with
  improvement): the greedy rule (the globally cheapest robot-task pair first, then the
  next) gives a first plan, which a local search on the team's total cost then improves:
  two tasks exchange robots, or three rotate theirs (a short chain), a task moves to a
  free robot or a waiting task takes a robot over, while the total falls. A local
  optimum, within 1-3 % of the optimum; O(n^3) per step up to :data:`CHAIN_MAX` tasks,
  pairwise exchanges only beyond.
- ``arrival``: each auction is awarded as it closes, to its cheapest bidder (btcap's
  first behaviour, kept as a baseline).

The order of the awards is :mod:`btcap.team.core.turns`; the strategies by name are
:mod:`btcap.team.allocation.strategies`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence, Set
from typing import TYPE_CHECKING

from btcap.team.messages import Bid

if TYPE_CHECKING:  # numpy (and scipy) only for the planning strategies: agents start fast
    import numpy as np

    Matrix = np.ndarray[tuple[int, int], np.dtype[np.float64]]

__all__ = [
    "CHAIN_MAX",
    "DEFERRAL",
    "PLANNING_MODULES",
    "QUEUE_MARGIN",
    "optimal_plan",
    "regret",
    "sequential_plan",
]

Plan = list[str | None]

#: What planning a batch of more than one task imports (about a second of CPU, which
#: must never hold an event loop: a robot imports them in a worker thread when it first
#: attaches a mission).
#: A single task is planned without them.
PLANNING_MODULES = ("numpy", "scipy.optimize")


def regret(bids: Sequence[Bid]) -> tuple[float, float, str]:
    """The ``auction`` strategy's turn key of an auction (smallest goes first), given its
    awardable free bids cheapest first: minus the regret, then the best bid and its robot
    (ties: the cheapest pair first). No bid: last."""
    if not bids:
        return (math.inf, math.inf, "")
    best = bids[0]
    loss = bids[1].cost - best.cost if len(bids) > 1 else math.inf
    return (-loss, best.cost, best.robot)


def _matrix(bids: Sequence[Sequence[Bid]], taken: Set[str]) -> tuple[list[str], Matrix]:
    """The robots not ``taken`` that bid, and each task's cost on each (inf: no bid)."""
    import numpy as np

    robots = sorted({b.robot for task in bids for b in task} - taken)
    index = {r: i for i, r in enumerate(robots)}
    cost: Matrix = np.full((len(bids), len(robots)), math.inf)
    for t, task in enumerate(bids):
        for b in task:
            if b.robot in index:
                cost[t, index[b.robot]] = min(cost[t, index[b.robot]], b.cost)
    return robots, cost


#: How much more a task left waiting costs than its best bid from a busy robot (see
#: :func:`optimal_plan`): more than 1, so that of two tasks that cost the same now, the
#: one that would end later if it waited starts first (the mission ends with its last
#: task). Chosen from ``python -m btcap.bench missiontime`` (1.25-2 gave the same).
#: On ``python -m btcap.bench strategytime``'s ``six`` it is all that tells this
#: strategy from ``sequential``, and no setting is best on every seed; nor were plans
#: aimed at the batch's latest end (1.0 with ties to the earliest end, the earliest end
#: within 5 % of the least total): per-seed differences there are the noise floor of
#: equally good decisions (see docs/allocation.md, "The default on every seed").
DEFERRAL = 1.5
#: A busy robot queues a task (``queue_after_current``) only if it is the task's best
#: robot by this share: below every other bid, free or busy, times (1 - margin).
QUEUE_MARGIN = 0.2


def optimal_plan(
    bids: Sequence[Sequence[Bid]],
    taken: Set[str],
    *,
    deferral: float = DEFERRAL,
    queue_margin: float = QUEUE_MARGIN,
) -> Plan:
    """For each task (its bids), the robot that gets it in an assignment of least total
    cost, each robot at most once and never one already ``taken``; None for a task that
    gets no robot.

    Bids from busy robots (``Bid.after`` > 0: for later, or to queue the task) say what a
    task left waiting would cost: ``deferral`` times its cheapest one. The free robots
    are planned first: when tasks outnumber them, the tasks that start are those for
    which starting now saves most against waiting (least total of the started tasks'
    costs plus the waiting tasks' deferral), so a free robot does not take a task a busy
    robot would do far more cheaply soon, and a task only it does well (or that would end
    last) goes first. Without bids from busy robots, the cheapest set of tasks that can
    run together starts. Before that, a busy robot that may queue one more task (not
    ``Bid.later``) is given a task if it is that task's best robot by ``queue_margin``
    against every other bid, free or busy (time-extended assignment: it starts the
    moment the robot is free), the largest saving first, one each.
    """
    plan: Plan = [None] * len(bids)
    _queue(bids, taken, plan, queue_margin)
    left = [t for t, robot in enumerate(plan) if robot is None]
    now = [[b for b in bids[t] if not b.after and not b.later] for t in left]
    if len(left) == 1:  # most auctions: one task, no matrix needed
        plan[left[0]] = _cheapest_free(now[0], taken)
        return plan
    import numpy as np
    from scipy.optimize import linear_sum_assignment  # scipy: only for this strategy

    robots, cost = _matrix(now, taken)
    wait = [min((b.cost for b in bids[t] if b.after or b.later), default=0.0) for t in left]
    if robots and left:
        if len(left) > len(robots) and any(wait):  # who waits matters: price the waiting
            cost = cost - deferral * np.array(wait)[:, None]
        finite = cost[np.isfinite(cost)]
        big = 2.0 * (1.0 + float(np.abs(finite).sum()))  # the stand-in for "no bid"
        rows, cols = linear_sum_assignment(np.where(np.isfinite(cost), cost, big))
        for t, r in zip(rows, cols, strict=True):
            if math.isfinite(cost[t, r]):
                plan[left[t]] = robots[r]
    return plan


def _cheapest_free(bids: Sequence[Bid], taken: Set[str]) -> str | None:
    """One task: what the Hungarian method gives a one-row matrix (the cheapest robot not
    ``taken``, ties to the robot whose name sorts first; none if no finite bid), without
    building the matrix (a robot's cost is its least bid, as in :func:`_matrix`)."""
    cost: dict[str, float] = {}
    for b in bids:
        if b.robot not in taken:
            cost[b.robot] = min(cost.get(b.robot, math.inf), b.cost)
    best: tuple[float, str] | None = None
    for robot in sorted(cost):
        c = cost[robot]
        if math.isfinite(c) and (best is None or c < best[0]):
            best = (c, robot)
    return None if best is None else best[1]


def _queue(bids: Sequence[Sequence[Bid]], taken: Set[str], plan: Plan, margin: float) -> None:
    """Give tasks to busy robots that may queue one and are their best robot by
    ``margin``, the largest saving first, one task each (in place)."""
    offers: list[tuple[float, int, str]] = []
    for t, task in enumerate(bids):
        if plan[t] is not None:
            continue
        for b in task:
            if not b.after or b.later or b.robot in taken:
                continue
            rest = min((o.cost for o in task if o.robot != b.robot), default=math.inf)
            if b.cost < (1.0 - margin) * rest:
                offers.append((b.cost - rest, t, b.robot))
    used = {r for r in plan if r is not None}
    for _saving, t, robot in sorted(offers):
        if plan[t] is None and robot not in used:
            plan[t] = robot
            used.add(robot)


def _greedy(cost: Matrix, got: list[int]) -> None:
    """Give tasks without a robot (-1 in ``got``) free robots in place, the cheapest
    remaining pair first, ties by task then robot index."""
    import numpy as np

    robots = cost.shape[1]
    used = {r for r in got if r >= 0}
    for flat in np.argsort(cost, axis=None, kind="stable"):
        t, r = divmod(int(flat), robots)
        if not math.isfinite(cost[t, r]):
            break
        if got[t] < 0 and r not in used:
            got[t] = r
            used.add(r)


#: Up to this many tasks or robots, the local search also rotates three tasks' robots
#: (a short chain; O(n^3) memory per step); beyond, pairwise exchanges only.
CHAIN_MAX = 64


def _square(cost: Matrix) -> Matrix:
    """``cost`` padded to a square matrix, "no bid" as a large finite cost: a padding row
    is a task nobody needs (free on any robot: its robot stays free), a padding column a
    robot nobody has (free for any task: that task waits for the next wave). A
    permutation of the square then places as many tasks as it can, and its least total
    is the rectangular optimum (the cheapest tasks start first)."""
    import numpy as np

    tasks, robots = cost.shape
    n = max(tasks, robots)
    finite = cost[np.isfinite(cost)]
    big = 2.0 * (1.0 + float(np.abs(finite).sum()))
    square: Matrix = np.zeros((n, n))
    square[:tasks, :robots] = np.where(np.isfinite(cost), cost, big)
    return square


def _improve(cost: Matrix, got: list[int]) -> None:
    """Best-improvement local search in place, on the team's total cost: exchange the
    robots of two tasks, or rotate those of three (a chain), while that lowers the total
    (strictly, so it ends). Moves to a free robot and a waiting task taking a robot over
    are exchanges with the padding (see :func:`_square`)."""
    import numpy as np

    tasks, robots = cost.shape
    sq = _square(cost)
    n = sq.shape[0]
    used = {r for r in got if r >= 0}
    spare = iter(r for r in range(n) if r not in used)
    perm = np.array([r if r >= 0 else next(spare) for r in got] + list(spare), dtype=np.intp)
    rows = np.arange(n)
    chains = n <= CHAIN_MAX
    for _step in range(n * n + 1):  # each step lowers the cost; a bound anyway
        now = sq[rows, perm]
        cross = sq[:, perm]  # cross[i, j]: task i on task j's robot
        tol = 1e-9 * max(1.0, float(np.abs(now).sum()))
        swap = cross + cross.T - now[:, None] - now[None, :]
        gain2 = float(swap.min())
        gain3 = 0.0
        if chains:  # i takes j's robot, j takes k's, k takes i's
            rot = cross[:, :, None] + cross[None, :, :] + cross.T[:, None, :]
            rot -= now[:, None, None] + now[None, :, None] + now[None, None, :]
            rot[rows, rows, :] = rot[:, rows, rows] = rot[rows, :, rows] = np.inf  # not 3
            gain3 = float(rot.min())
        if min(gain2, gain3) >= -tol:
            break
        if gain2 <= gain3:
            i, j = divmod(int(np.argmin(swap)), n)
            perm[i], perm[j] = perm[j], perm[i]
        else:
            a, b, c = (int(x) for x in np.unravel_index(int(np.argmin(rot)), rot.shape))
            perm[a], perm[b], perm[c] = perm[b], perm[c], perm[a]
    for t in range(tasks):
        r = int(perm[t])
        got[t] = r if r < robots and math.isfinite(cost[t, r]) else -1


def sequential_plan(bids: Sequence[Sequence[Bid]], taken: Set[str]) -> Plan:
    """The greedy assignment (cheapest robot-task pair first, then the next), improved by
    exchanges, chains of three, moves to free robots and waiting tasks taking robots over;
    same contract as :func:`optimal_plan` (time-extended bids are left out)."""
    if len(bids) == 1:  # one task: the greedy choice, which nothing improves
        return [_cheapest_free([b for b in bids[0] if not b.later], taken)]
    robots, cost = _matrix([[b for b in task if not b.later] for task in bids], taken)
    if not robots or not bids:
        return [None] * len(bids)
    got = [-1] * len(bids)
    _greedy(cost, got)
    _improve(cost, got)
    return [robots[r] if r >= 0 else None for r in got]
