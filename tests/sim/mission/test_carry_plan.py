"""The pool mission's carry plan (which carries waiting are offered to the carriers free
now) and its stand-by lanes after a carry waited: trees ticked on a manual clock."""

from __future__ import annotations

import anyio
import numpy as np
import pytest

from btcap import Leaf, ParallelForEach, State, Tree
from btcap.actors import ManualClock
from btcap.sim.mission.carryplan import (
    FROM_AREA_S,
    CarryPace,
    CarryTurns,
    carrier_pace,
    carry_metres,
    carry_plan,
)
from btcap.sim.mission.pool import ObjectLane, ObjectPool, StandByLane, pool_mission_tree
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import paper_team


def test_the_carry_plan_ends_the_carries_left_soonest_not_the_longest_first() -> None:
    # full-team-6 seed 1 (pool): carries of 198, 166 and 124 s left, one Husky free at
    # 416 s, the other at 463 s. The allocation gave the Husky free first the longest
    # (the dearest to leave waiting): it ended at 739 s. The two shorter ones on that
    # Husky, the longest on the other, end at 706 s.
    seconds = {9: 198.0, 2: 166.0, 7: 124.0}
    plan = carry_plan([416.0, 463.0], list(seconds.items()))
    starts = {k: (carrier, start) for k, carrier, start in plan}
    assert starts[9] == (1, 463.0)
    assert {starts[2][0], starts[7][0]} == {0}
    assert max(start + seconds[k] for k, _, start in plan) == 706.0
    # both free at once: the longest alone on one, the two others on the other
    plan = carry_plan([0.0, 0.0], list(seconds.items()))
    assert {k for k, _, start in plan if start == 0.0} == {9, 7}
    assert max(start + seconds[k] for k, _, start in plan) == 290.0
    # beyond EXHAUSTIVE carries, the longest first, each to the carrier free soonest
    many = [(k, float(k)) for k in range(1, 10)]
    assert [k for k, _, _ in carry_plan([0.0, 5.0], many)] == list(range(9, 0, -1))


def test_a_carrier_busy_is_free_after_its_carry_from_where_it_began() -> None:
    pace = CarryPace(speed_mps=1.0, op_s=8.0)
    turns = CarryTurns(2, pace, lambda cell: float(cell[1]))
    turns.offer(100.0, {}, {1: (0, 50)})  # began from standing by: half the drive out
    assert turns.free_at(100.0, {1: (0, 50)}) == [100.0, 100.0 + 1.5 * 50 + 8]
    turns.offer(190.0, {}, {})  # it ended: a carrier came free at the area
    turns.offer(190.0 + FROM_AREA_S, {}, {2: (0, 40)})  # the next began there: all of it
    assert turns.free_at(200.0, {2: (0, 40)}) == [200.0, 193.0 + 2 * 40 + 8]
    assert turns.free_at(400.0, {2: (0, 40)}) == [400.0, 401.0]  # late: not free yet
    assert carrier_pace(list(paper_team().values())) == pace  # the Husky alone carries


class Carry(Leaf):
    """Stands in for a carry: RUNNING (a robot has it) if ``taken``, else UNASSIGNED (its
    auction under way), SUCCEEDED once ``done``; counts its ticks and resets."""

    def __init__(self, taken: bool) -> None:
        super().__init__("carry")
        self.taken, self.done, self.ticks, self.resets = taken, False, 0, 0

    def on_tick(self) -> State:
        self.ticks += 1
        if self.done:
            return State.SUCCEEDED
        return State.RUNNING if self.taken else State.UNASSIGNED

    def on_reset(self) -> None:
        self.resets += 1


class Identify(Leaf):
    """Never ticked: the objects are listed known contaminated."""

    def on_tick(self) -> State:
        raise AssertionError("a known contaminated object is not identified again")


async def test_the_pool_offers_the_carries_its_plan_starts_now() -> None:
    # A corridor, the decontamination area at its west end: carries of 26, 95, 79 and 58
    # m. The first is under way (begun from standing by: its carrier free in about
    # 1.5 x 26 + 8 = 47 s); the other three then wait, one carrier free. Offered all
    # at once, the free carrier took the longest (198 s: the others ended at 322 s); the
    # plan offers the 58 m carry, then the 79 m one on the same carrier (ends 290 s),
    # and leaves the longest for the carrier free at 47 s (ends 245 s).
    grid = GridMap.from_array(np.ones((1, 120), dtype=bool), start=(0, 0), decon_area=(0, 0))
    cells = {0: 26, 1: 95, 2: 79, 3: 58}
    carries = [Carry(taken=k == 0) for k in cells]
    lanes = [ObjectLane(f"o{k}", children=[Identify("identify"), carries[k]]) for k in cells]
    pool = ObjectPool(
        "pool", children=lanes, key=0, carriers=2, grid=grid, carry_pace=CarryPace(1.0, 8.0)
    )
    clock = ManualClock()
    tree = Tree(pool, clock=clock)
    with anyio.fail_after(10):
        pool.set_input("items", [(0, 0, cells[0], 1)])
        pool.set_input("complete", True)
        tree.tick()
        assert carries[0].ticks == 1  # a carrier free: offered at once
        await clock.advance(1.0)
        pool.set_input("items", [(k, 0, c, 1) for k, c in cells.items()])
        for _ in range(3):
            tree.tick()
            await clock.advance(0.5)
    assert carries[3].ticks == 3  # offered: its auction runs
    assert carries[1].ticks == carries[2].ticks == 0  # they wait for their carrier
    carries[3].taken = True  # the free carrier took it
    tree.tick()
    assert carries[1].ticks == carries[2].ticks == 0  # no carrier free now
    carries[0].done = True  # the first carrier came free: the longest is its
    pool.set_input("items", [(k, 0, c, 1) for k, c in cells.items() if k != 0])
    with anyio.fail_after(10):
        await clock.advance(1.0)
        tree.tick()  # the carry ends in this tick: the plan sees it in the next
        tree.tick()
    assert carries[1].ticks == 1
    assert carries[2].ticks == 0


async def test_a_carry_offered_then_not_planned_now_has_its_auction_called_off() -> None:
    grid = GridMap.from_array(np.ones((1, 120), dtype=bool), start=(0, 0), decon_area=(0, 0))
    carries = [Carry(taken=False), Carry(taken=False)]
    lanes = [ObjectLane(f"o{k}", children=[Identify("identify"), carries[k]]) for k in (0, 1)]
    pool = ObjectPool(
        "pool", children=lanes, key=0, carriers=1, grid=grid, carry_pace=CarryPace(1.0, 8.0)
    )
    clock = ManualClock()
    tree = Tree(pool, clock=clock)
    pool.set_input("items", [(0, 0, 90, 1)])
    pool.set_input("complete", True)
    tree.tick()  # the only carry: offered
    assert carries[0].ticks == 1
    with anyio.fail_after(10):
        await clock.advance(1.0)
    pool.set_input("items", [(0, 0, 90, 1), (1, 0, 10, 1)])
    tree.tick()  # one carrier: the shorter first (the least sum of ends)
    tree.tick()
    assert carries[0].resets >= 1
    assert lanes[0].children[1].state is State.IDLE
    assert carries[1].ticks == 2


class Runs(Leaf):
    """RUNNING for ever (a drive to stand by)."""

    def on_tick(self) -> State:
        return State.RUNNING


def test_a_carrier_stands_by_again_at_an_object_once_no_carry_waits() -> None:
    # full-team-6 seed 3: a carry waiting ended every stand-by lane as done with its
    # object, in one tick the whole plan, so no carrier stood by again: a Husky idle
    # from 228 to 245 s while two objects awaited identification.
    stand = StandByLane("standby_1", children=[Runs("standby")])
    each = ParallelForEach("each_standby", children=[stand], key=0, retry_failed=True)
    tree = Tree(each)
    plan = [(4, 1, 2), (5, 3, 3)]
    each.set_input("items", plan)
    each.set_input("complete", False)  # more objects may be found
    stand.set_input("listed", plan)
    for waiting, stands in ((0, True), (1, False), (0, True)):
        stand.set_input("waiting", waiting)
        tree.tick()
        assert (stand.state is State.RUNNING) is stands
    assert stand.inputs["item"][0] == 4  # the first in the plan, again
    tree_of = pool_mission_tree(standby=2)
    each_standby = next(n for n in tree_of.nodes() if n.name == "each_standby")
    assert each_standby.options["retry_failed"]


@pytest.mark.parametrize("robots", [3, 6])
def test_the_runner_gives_the_pool_its_carriers_and_their_pace(robots: int) -> None:
    from btcap.bench.allocation.missionbound import scenario
    from btcap.sim.running.runner import _mission

    s = scenario("full-team" if robots == 3 else "full-team-6", 1, "pool")
    tree = _mission(s, s.grid())
    pool = next(n for n in tree.nodes() if isinstance(n, ObjectPool))
    assert pool.options["carriers"] == robots // 3
    assert pool._carries is not None  # priced: the Huskies carry at 1 m/s, 8 s
    assert carry_metres(s.grid())(s.grid().decon_area) == 0.0
