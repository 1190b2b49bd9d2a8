"""Award order and plans of the allocation strategies, on explicit bid matrices."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from btcap.team.allocation.strategies import check_strategy, names
from btcap.team.core.planning import optimal_plan, regret, sequential_plan
from btcap.team.core.turns import ARRIVAL, AUCTION, SEQUENTIAL
from btcap.team.ids import AuctionId
from btcap.team.messages import Bid

A1 = AuctionId("a", 1)


def bid(robot: str, cost: float) -> Bid:
    return Bid(A1, robot, cost, "i")


def bids_of(cost: np.ndarray, missing: float = math.inf) -> list[list[Bid]]:
    """Task-major bids from a tasks x robots matrix (robot j is ``r{j:02d}``)."""
    return [
        sorted(
            (bid(f"r{r:02d}", float(c)) for r, c in enumerate(row) if c != missing),
            key=lambda b: b.cost,
        )
        for row in cost
    ]


def total(cost: np.ndarray, robots: list[str | None]) -> float:
    return sum(float(cost[t, int(r[1:])]) for t, r in enumerate(robots) if r is not None)


def greedy_total(cost: np.ndarray) -> float:
    c = cost.astype(float).copy()
    paid = 0.0
    for _ in range(min(c.shape)):
        t, r = np.unravel_index(int(np.argmin(c)), c.shape)
        paid += float(c[t, r])
        c[t, :] = math.inf
        c[:, r] = math.inf
    return paid


def test_the_plans_escape_the_classic_trap() -> None:
    t1 = [bid("b", 1.0), bid("c", 2.0)]
    t2 = [bid("b", 2.0), bid("c", 100.0)]
    for planner in (optimal_plan, sequential_plan):
        assert planner([t1, t2], set()) == ["c", "b"]  # 4, where greedy pays 101
        assert planner([t1, t2], {"b"}) == ["c", None]
        assert planner([[], t2], set()) == [None, "b"]
        assert planner([], set()) == []
    assert AUCTION.plan([t1, t2], set()) is None
    assert ARRIVAL.plan([t1, t2], set()) is None
    assert SEQUENTIAL.plan([t1, t2], set()) == ["c", "b"]


def test_regret_puts_the_task_that_loses_most_by_waiting_first() -> None:
    t1 = [bid("b", 1.0), bid("c", 2.0)]  # loses 1 if b goes elsewhere
    t2 = [bid("b", 2.0), bid("c", 100.0)]  # loses 98
    assert min([t1, t2], key=regret) is t2
    only = [bid("c", 50.0)]  # a single bidder: it waits or gets it now
    assert min([t1, t2, only], key=regret) is only
    # Single bidders each (the lone Husky of Fig. 4): the cheapest task first.
    assert min([[bid("h", 9.0)], [bid("h", 3.0)]], key=regret) == [bid("h", 3.0)]
    assert regret([]) > regret(only)


def test_sequential_improves_greedy_with_exchanges_and_moves_to_free_robots() -> None:
    # Greedy: t0->r0 (1), t1->r1 (5), t2->r2 (9) = 15. Exchanging t1 and t2's robots
    # (r1 on t2: 4, r2 on t1: 6) gives 11; then r3 (free) does t1 for 2: 7.
    cost = np.array(
        [
            [1.0, 8.0, 8.0, 9.0],
            [9.0, 5.0, 6.0, 8.0],
            [9.0, 4.0, 9.0, 9.0],
        ]
    )
    cost[1, 3] = 2.0
    got = sequential_plan(bids_of(cost), set())
    assert total(cost, got) == pytest.approx(7.0)
    assert len({r for r in got if r is not None}) == 3


def test_sequential_serves_as_many_tasks_as_it_can_like_the_optimum() -> None:
    # Only r0 can do t0; greedy gives r0 t1 (1 < 3). Moving t1 to r1 (2) serves t0 too:
    # a task left without a robot counts as a "no bid" cost, far above any bid.
    cost = np.array([[3.0, math.inf], [1.0, 2.0]])
    assert sequential_plan(bids_of(cost), set()) == ["r00", "r01"]
    assert optimal_plan(bids_of(cost), set()) == ["r00", "r01"]


def test_sequential_rotates_three_robots_where_no_exchange_of_two_helps() -> None:
    # Greedy: t0-r2 (1), t1-r0 (1), t2-r1 (9) = 11; no two tasks gain by exchanging
    # robots, but the chain t0->r1, t1->r2, t2->r0 costs 3 + 2 + 5 = 10, the optimum.
    cost = np.array([[7.0, 3.0, 1.0], [1.0, 7.0, 2.0], [5.0, 9.0, 9.0]])
    assert sequential_plan(bids_of(cost), set()) == ["r01", "r02", "r00"]
    assert total(cost, optimal_plan(bids_of(cost), set())) == 10.0


def test_with_more_tasks_than_robots_the_first_wave_is_the_cheapest() -> None:
    # Greedy: t0-r0 (1), then t1-r1 (4): 5. Letting t2 take r1 over (2) and t1 wait
    # costs 3, the least any first wave of two tasks costs.
    cost = np.array([[1.0, 3.0], [9.0, 4.0], [10.0, 2.0]])
    assert sequential_plan(bids_of(cost), set()) == ["r00", None, "r01"]


@settings(max_examples=150, deadline=None)
@given(
    st.integers(1, 9).flatmap(
        lambda t: st.integers(1, 9).flatmap(
            lambda r: st.lists(
                st.one_of(st.integers(1, 60).map(float), st.just(math.inf)),
                min_size=t * r,
                max_size=t * r,
            ).map(lambda xs: np.array(xs).reshape(t, r))
        )
    )
)
def test_sequential_plans_are_valid_and_no_exchange_or_chain_of_three_improves(
    cost: np.ndarray,
) -> None:
    got = sequential_plan(bids_of(cost), set())
    used = [r for r in got if r is not None]
    assert len(used) == len(set(used))
    assert all(math.isfinite(cost[t, int(r[1:])]) for t, r in enumerate(got) if r)
    # No more than greedy's cost when every task or robot is served (a local search:
    # serving more can take a longer chain than three, which the optimum finds).
    finite = np.where(np.isfinite(cost), cost, 1e6)
    if len(used) == min(cost.shape):
        assert total(cost, got) <= greedy_total(finite) + 1e-9
    # Locally optimal: padded to a square with "no bid" dear and waiting free, no
    # rotation of two or three tasks' robots lowers the total.
    n = max(cost.shape)
    sq = np.zeros((n, n))
    sq[: cost.shape[0], : cost.shape[1]] = finite
    perm = [int(r[1:]) if r else -1 for r in got] + [-1] * (n - len(got))
    spare = iter(sorted(set(range(n)) - {p for p in perm if p >= 0}))
    perm = [p if p >= 0 else next(spare) for p in perm]
    now = sum(sq[t, perm[t]] for t in range(n))
    for k in (2, 3):
        for tasks in itertools.permutations(range(n), k):
            moved = list(perm)
            for a, b in zip(tasks, tasks[1:] + tasks[:1], strict=True):
                moved[a] = perm[b]
            assert sum(sq[t, moved[t]] for t in range(n)) >= now - 1e-6


@pytest.mark.parametrize("seed", range(8))
def test_sequential_is_a_valid_local_optimum_between_greedy_and_the_optimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    tasks, robots = rng.integers(2, 12, size=2)
    cost = rng.uniform(1.0, 100.0, size=(tasks, robots))
    cost[rng.random(cost.shape) < 0.2] = math.inf  # some robots cannot do some tasks
    taken = {f"r{r:02d}" for r in range(robots) if rng.random() < 0.15}
    got = sequential_plan(bids_of(cost), taken)
    used = [r for r in got if r is not None]
    assert len(used) == len(set(used))
    assert not set(used) & taken
    assert all(math.isfinite(cost[t, int(r[1:])]) for t, r in enumerate(got) if r)
    free = [r for r in range(robots) if f"r{r:02d}" not in taken]
    sub = cost[:, free]
    finite = np.where(np.isfinite(sub), sub, 1e9)
    rows, cols = linear_sum_assignment(finite)
    best = sum(float(sub[t, r]) for t, r in zip(rows, cols, strict=True) if sub[t, r] < 1e9)
    greedy = greedy_total(np.where(np.isfinite(sub), sub, 1e9)) if sub.size else 0.0
    served = [t for t, r in enumerate(got) if r is not None]
    # No pair of served tasks gains from exchanging robots, no task from a free robot.
    for i in served:
        ri = int(got[i][1:])  # type: ignore[index]
        for j in served:
            rj = int(got[j][1:])  # type: ignore[index]
            assert cost[i, rj] + cost[j, ri] >= cost[i, ri] + cost[j, rj] - 1e-9
        for r in free:
            if f"r{r:02d}" not in used:
                assert cost[i, r] >= cost[i, ri] - 1e-9
    if len(served) == min(len(free), tasks) and greedy < 1e9:
        assert best - 1e-9 <= total(cost, got) <= greedy + 1e-9


def test_strategy_names_are_checked() -> None:
    assert names()[:5] == ["auction", "sequential", "optimal", "arrival", "consensus"]
    assert check_strategy("sequential") == "sequential"
    with pytest.raises(ValueError, match="'fastest': expected one of auction, sequential"):
        check_strategy("fastest")


def later(robot: str, cost: float, after: float) -> Bid:
    """A time-extended bid: ``robot`` is busy for ``after`` first."""
    return Bid(A1, robot, cost, "i", after, later=True)


def test_a_task_a_busy_robot_does_far_cheaper_soon_waits_for_it() -> None:
    # one free robot f; "near" is cheap for f (10) but busy b would do it for 12 in all;
    # "far" costs f 50 and anyone else 200 if it waits: f takes far, near waits for b
    near = [bid("f", 10.0), later("b", 12.0, 5.0)]
    far = [bid("f", 50.0), later("c", 200.0, 100.0)]
    assert optimal_plan([near, far], set()) == [None, "f"]
    # without the time-extended bids: the cheapest task starts, as before
    assert optimal_plan([near[:1], far[:1]], set()) == ["f", None]
    # a busy robot is never planned
    assert optimal_plan([[later("b", 1.0, 0.5)]], set()) == [None]


def test_of_two_tasks_costing_the_same_the_one_that_would_end_later_starts() -> None:
    # f costs 100 on either; waiting, "short" costs 100 + 10 of wait, "long" 300 + 10
    short = [bid("f", 100.0), later("g", 110.0, 10.0)]
    long = [bid("f", 100.0), later("g", 310.0, 10.0)]
    assert optimal_plan([short, long], set()) == [None, "f"]


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 6), st.integers(0, 10_000))
def test_time_extended_bids_change_nothing_when_every_task_gets_a_robot(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    cost = rng.uniform(1.0, 100.0, (n, n + 1))
    plain = bids_of(cost)
    extended = [[*b, later("busy", float(rng.uniform(1, 300)), 1.0)] for b in plain]
    assert total(cost, optimal_plan(extended, set())) == pytest.approx(
        total(cost, optimal_plan(plain, set()))
    )
    assert "busy" not in optimal_plan(extended, set())


def queued(robot: str, cost: float, after: float) -> Bid:
    """``robot`` is busy for ``after`` and may queue the task (``queue_after_current``)."""
    return Bid(A1, robot, cost, "i", after)


def test_a_busy_robot_queues_a_waiting_task_only_as_its_best_robot_by_the_margin() -> None:
    # f is free and takes "a"; "b" waits: q (busy, may queue) does it for 20 against
    # 40 on f: q queues it. "c": q2 bids 30 against f's 33, within the margin: it waits.
    a = [bid("f", 5.0), queued("q", 50.0, 10.0)]
    b = [bid("f", 40.0), queued("q", 20.0, 10.0)]
    c = [bid("f", 33.0), queued("q2", 30.0, 10.0)]
    assert optimal_plan([a, b, c], set()) == ["f", "q", None]
    # one queued task per robot, the largest saving first
    d = [bid("f", 100.0), queued("q", 10.0, 5.0)]
    assert optimal_plan([a, b, d], set()) == ["f", None, "q"]
    # without the margin rule no busy robot is planned
    assert optimal_plan([a, b, c], set(), queue_margin=1.0) == ["f", None, None]


def _hungarian_one(bids: list[Bid], taken: set[str]) -> str | None:
    """The general path for one task: its bid matrix through scipy's Hungarian method."""
    robots = sorted({b.robot for b in bids} - taken)
    if not robots:
        return None
    row = np.full((1, len(robots)), math.inf)
    for b in bids:
        if b.robot in robots:
            j = robots.index(b.robot)
            row[0, j] = min(row[0, j], b.cost)
    finite = row[np.isfinite(row)]
    big = 2.0 * (1.0 + float(np.abs(finite).sum()))
    _, cols = linear_sum_assignment(np.where(np.isfinite(row), row, big))
    return robots[cols[0]] if math.isfinite(row[0, cols[0]]) else None


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.sampled_from(["a", "b", "c", "d", "e"]),
            st.sampled_from([0.0, 1.0, 2.0, 2.5, math.inf, math.nan]),
        ),
        max_size=8,
    ),
    st.sets(st.sampled_from(["a", "b", "c", "d", "e"]), max_size=3),
)
def test_one_task_plans_as_the_hungarian_method_ties_included(
    pairs: list[tuple[str, float]], taken: set[str]
) -> None:
    bids = [bid(r, c) for r, c in pairs]
    assert optimal_plan([bids], taken) == [_hungarian_one(bids, taken)]
    assert sequential_plan([bids], taken) == [_hungarian_one(bids, taken)]  # no numpy either
