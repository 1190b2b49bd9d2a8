"""The mission-time bound's work on objects as a preemptive schedule (one robot at a time
on each object), and each robot's own reach, against values worked out by hand; never
above a schedule made in hindsight.

Sans-IO: maps, models and the simulation's draws, no mission runs.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import OptimizeResult

from btcap.bench.allocation.missionbound import scenario
from btcap.sim.mission import preemptive
from btcap.sim.mission.bound import mission_bound, scenario_bound
from btcap.sim.mission.hindsight import scenario_hindsight
from btcap.sim.mission.preemptive import Drive, Job, preemptive_end
from btcap.sim.mission.presence import Presence
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import OperationModel, RobotModel
from tests.sim.mission.test_bound_relay import CARRIER
from tests.sim.mission.test_mission_bound import DRONE, corridor


def identifier(speed_mps: float) -> RobotModel:
    """Identifies in 100 s and does nothing else."""
    return RobotModel(cost_factor=1.0, speed_mps=speed_mps, identify=OperationModel(100.0))


def test_an_object_known_alone_keeps_one_robot_working() -> None:
    # Two robots; a 100 s job known at 0, two more at 50. Spread over the robots after
    # each release the work says 150 s (300 / 2; 50 + 200 / 2), but until 50 only one
    # robot can work: 250 s are left for two at 50, so 175 s at the least.
    both = [Presence(), Presence()]
    jobs = [Job(((r, 100.0, False),)) for r in (0.0, 50.0, 50.0)]
    assert preemptive_end(both, jobs) == pytest.approx(175.0, abs=0.02)
    # driving that must come after 0 fills the idle robot's time before 50; after 50 it
    # adds to the end
    assert preemptive_end(both, jobs, [Drive(0.0, 50.0)]) == pytest.approx(175.0, abs=0.02)
    assert preemptive_end(both, jobs, [Drive(50.0, 10.0)]) == pytest.approx(180.0, abs=0.02)
    # one robot absent until 50: the other does the first job, then all three share
    late = [Presence(), Presence(start=50.0)]
    assert preemptive_end(late, jobs) == pytest.approx(175.0, abs=0.02)
    assert preemptive_end([Presence()], jobs) == pytest.approx(300.0, abs=0.02)
    # 30 s of driving after 50 s is also driving after 0: a need of 10 s then adds nothing
    alone = [Presence()]
    assert preemptive_end(alone, [], [Drive(0.0, 10.0), Drive(50.0, 30.0)]) == pytest.approx(
        80.0, abs=0.02
    )
    assert preemptive_end(alone, [], [Drive(0.0, 40.0), Drive(50.0, 30.0)]) == pytest.approx(
        80.0, abs=0.02
    )


def test_a_carry_may_be_the_driving_for_other_objects() -> None:
    # One robot carries an object for 10 s from 5 s on, and must move 10 s after 5 s for
    # objects found later: carrying the first to the decontamination area may be its way
    # to them, so 15 s; driving the later ones' own carries does not count twice: 25 s.
    alone = [Presence()]
    carry = [Job(((5.0, 10.0, True),))]
    assert preemptive_end(alone, carry, [Drive(5.0, 10.0)]) == pytest.approx(15.0, abs=0.02)
    own = [Drive(5.0, 10.0, frozenset({0}))]
    assert preemptive_end(alone, carry, own) == pytest.approx(25.0, abs=0.02)
    # work that is not moving never counts as driving
    work = [Job(((5.0, 10.0, False),))]
    assert preemptive_end(alone, work, [Drive(5.0, 10.0)]) == pytest.approx(25.0, abs=0.02)


def test_the_bound_waits_while_one_object_is_known() -> None:
    # A corridor: the drone finds the object at the start at 1 s, those at 39 and 40 m at
    # 14 s (its 14th exploration). Two fast identifiers (100 s each): after 1 s the work
    # spread over both says 1 + 300 / 2 = 151 s; but until 14 s one of them has nothing
    # to do, so 87 + 200 s are left for two at 14 s: 157.5 s.
    grid = corridor()
    fast = identifier(100.0)
    objects = [((0, 0), False), ((0, 39), False), ((0, 40), False)]
    b = mission_bound(grid, [DRONE, fast, fast], objects)
    assert b.seconds == pytest.approx(157.5)
    assert b.binding == "release"
    assert max(b.chains_s, b.work_s) < 151.0
    # a carrier beside them adds nothing to identify with: the identifiers alone wait
    # (the three together, one at a time on each object, say 114 s; spread, 101 s)
    carts = mission_bound(grid, [DRONE, fast, fast, CARRIER], objects)
    assert carts.seconds == pytest.approx(157.5)


def test_each_robot_is_no_farther_than_it_can_have_driven() -> None:
    # A corridor of 81 m, the start in its middle: objects at both ends, found at 14 s.
    # One identifier drives 10 m/s, the other 1 m/s: at 14 s the slow one is 14 m from
    # the start at most, so one of them drives 26 m more (2.6 s at the fastest speed):
    # 14 + (200 + 2.6) / 2 = 115.3 s. Both as far as the fast one could be: 114 s.
    grid = GridMap.from_array(np.ones((1, 81), dtype=bool), start=(0, 40), decon_area=(0, 40))
    models = [DRONE, identifier(10.0), identifier(1.0)]
    b = mission_bound(grid, models, [((0, 0), False), ((0, 80), False)])
    assert b.seconds == pytest.approx(115.3)
    assert b.chains_s == pytest.approx(114.0)


@pytest.mark.parametrize(
    ("name", "seed"), [("huskies-bebop-joins", 10), ("huskies-bebop-joins", 4)]
)
def test_the_bound_stays_below_a_schedule_made_in_hindsight(name: str, seed: int) -> None:
    # huskies-bebop-joins seed 10: the one-at-a-time part binds (609 s, 606 s before)
    s = scenario(name, seed, "pool")
    h = scenario_hindsight(s, tries=3)
    assert h is not None
    assert scenario_bound(s).seconds <= h.seconds


def test_a_solver_that_cannot_tell_gives_the_span_start_not_a_later_end(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Only "infeasible" moves the search to a later span: a solver that gave up
    (numerical trouble, a limit) must not push the bound above every schedule."""
    both = [Presence(), Presence()]
    jobs = [Job(((r, 100.0, False),)) for r in (0.0, 50.0, 50.0)]
    gave_up = OptimizeResult(status=4, x=None, message="numerical difficulties")
    monkeypatch.setattr(preemptive, "linprog", lambda *a, **k: gave_up)
    # two jobs come at 50, so the end is sought from the span that starts there: its
    # start is the answer (before, the search went on past every span: inf)
    assert preemptive_end(both, jobs) == pytest.approx(50.0, abs=0.01)
    infeasible = OptimizeResult(status=2, x=None, message="infeasible")
    monkeypatch.setattr(preemptive, "linprog", lambda *a, **k: infeasible)
    assert preemptive_end(both, jobs) == float("inf")
