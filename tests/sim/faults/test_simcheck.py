"""The invariants of ``btcap sim-test`` on explicit events: each one breaks when it should
and holds when it should."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from btcap.sim.faults.check import Checker
from btcap.sim.faults.shrink import kind_of

TICK = 0.25


def _run_both(
    checker: Checker, first: tuple[str, int], second: tuple[str, int], until: float
) -> None:
    """Two runs of task t1 ticking together from 0 to ``until``."""
    t = 0.0
    while t <= until:
        checker.tick(*first, "t1", t)
        checker.tick(*second, "t1", t)
        t += TICK


def test_two_runs_of_one_task_never_act_at_once() -> None:
    """Not even for a tick: the second run's first tick while the first acts breaks it."""
    bad = Checker()
    _run_both(bad, ("r1", 1), ("r2", 2), 0.0)
    assert [kind_of(v) for v in bad.violations] == ["double execution"]
    assert "t1 runs on r1 (run 1, acting since 0.000) and r2 (run 2" in bad.violations[0]
    assert bad.double_ticks == 1


def test_a_run_acts_until_it_ends_even_without_ticks() -> None:
    """A run that stopped ticking (cut off, frozen) still acts until it is stopped."""
    checker = Checker()
    checker.tick("r1", 1, "t1", 0.0)
    checker.tick("r2", 2, "t1", 5.0)
    assert [kind_of(v) for v in checker.violations] == ["double execution"]


def test_runs_one_after_the_other_never_overlap() -> None:
    checker = Checker()
    for k in range(20):
        checker.tick("r1", 1, "t1", k * TICK)
    checker.end(1)
    for k in range(19, 40):  # at the instant the first ended, too
        checker.tick("r2", 2, "t1", k * TICK)
    assert checker.violations == []
    assert checker.double_ticks == 0


def test_a_result_given_up_on_is_never_credited() -> None:
    checker = Checker()
    checker.tick("r1", 1, "t1", 0.0)
    checker.credit("op", "t1", "r1", 1, "op:t1#1", 1.0)
    assert checker.violations == []
    checker.tick("r2", 2, "t2", 1.0)
    checker.declared_failed("r2", 1.5)
    checker.gave_up("op:t2#2")
    checker.credit("op", "t2", "r2", 2, "op:t2#2", 2.0)
    assert [kind_of(v) for v in checker.violations] == ["credited after failure"]
    checker.credit("op", "t3", "r2", 99, "op:t3#3", 2.0)
    assert "credited to unknown run 99" in checker.violations[-1]


def test_a_decline_of_a_run_held_is_caught() -> None:
    checker = Checker()
    checker.declined("r1", "op:t1#1", False, "busy", 1.0)
    assert checker.violations == []
    checker.declined("r1", "op:t1#1", True, "awarded before", 1.0)
    assert [kind_of(v) for v in checker.violations] == ["declined but running"]


def _agent(**sizes: int) -> Any:
    """An agent-shaped object whose tables have the given sizes."""

    def table(name: str) -> dict[int, None]:
        return dict.fromkeys(range(sizes.get(name, 0)))

    mc = SimpleNamespace(
        origin=SimpleNamespace(tracked=table("tracked")),
        active=table("active"),
        host=SimpleNamespace(hosted=table("hosted"), finished=table("finished")),
        executor=SimpleNamespace(local_runs=table("local")),
    )
    stats = SimpleNamespace(by_reason=table("reasons"))
    return SimpleNamespace(
        robot="r1",
        team=SimpleNamespace(members=table("members")),
        repository=SimpleNamespace(team=table("repo")),
        mission_control=mc,
        system=SimpleNamespace(pending_asks=0, transport=SimpleNamespace(stats=stats)),
    )


def test_tables_beyond_what_the_team_can_need_are_caught() -> None:
    checker = Checker()
    checker.bounds(1.0, [_agent(members=4, repo=4, tracked=3, hosted=2)], names=5, tasks=3)
    assert checker.violations == []
    checker.bounds(2.0, [_agent(members=9, hosted=3)], names=5, tasks=3)
    assert [kind_of(v) for v in checker.violations] == ["unbounded", "unbounded"]
    assert "r1's members hold 9 (bound 4)" in checker.violations[0]
