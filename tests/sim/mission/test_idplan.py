"""The pool mission's identification plan (:mod:`btcap.sim.mission.idplan`), on its own."""

from __future__ import annotations

from btcap.sim.mission.idplan import Identifier, Turns, Waiting, identifier_pace, plan
from btcap.sim.world.model import paper_team


def _waiting(*cells: tuple[int, int], waited: float = 0.0) -> list[Waiting]:
    return [Waiting(k, c, waited) for k, c in enumerate(cells)]


def test_one_identifier_tours_nearest_first_from_where_it_stands() -> None:
    # found at the two ends of a corridor in turn: oldest first would cross it 3 times
    objects = _waiting((0, 100), (0, 2), (0, 102), (0, 4))
    order = plan([Identifier((0, 0))], objects, speed=1.0, op_s=2.0, cap_s=240.0)
    assert order == [(1, 0), (3, 0), (0, 0), (2, 0)]


def test_an_object_that_waited_too_long_goes_first() -> None:
    objects = [Waiting(0, (0, 100), 300.0), Waiting(1, (0, 2), 10.0)]
    order = plan([Identifier((0, 0))], objects, speed=1.0, op_s=2.0, cap_s=240.0)
    assert [k for k, _ in order] == [0, 1]
    # no cap reached: the near one first; cap 0: always the oldest first
    assert [k for k, _ in plan([Identifier((0, 0))], objects, speed=1, op_s=2, cap_s=400)] == [1, 0]
    assert [k for k, _ in plan([Identifier((0, 0))], objects, speed=1, op_s=2, cap_s=0)] == [0, 1]


def test_two_identifiers_each_take_the_objects_near_them() -> None:
    robots = [Identifier((0, 0)), Identifier((0, 100))]
    objects = _waiting((0, 98), (0, 3), (0, 95), (0, 6))
    order = dict(plan(robots, objects, speed=1.0, op_s=2.0, cap_s=240.0))
    assert order == {0: 1, 1: 0, 2: 1, 3: 0}


def test_an_identifier_whose_place_is_unknown_takes_the_oldest() -> None:
    objects = _waiting((0, 50), (0, 2))
    assert plan([Identifier()], objects, speed=1.0, op_s=2.0, cap_s=240.0)[0] == (0, 0)


def test_identification_time_spreads_work_over_identifiers() -> None:
    # priced in time: with 60 s identifications (Huskies), the second object goes to
    # the other identifier 20 s away rather than after the first one's identification
    robots = [Identifier((0, 0)), Identifier((0, 20))]
    objects = _waiting((0, 1), (0, 2))
    assert dict(plan(robots, objects, speed=1.0, op_s=60.0, cap_s=240.0)) == {0: 0, 1: 1}
    assert dict(plan(robots, objects, speed=1.0, op_s=0.0, cap_s=240.0)) == {0: 0, 1: 0}


def test_turns_go_to_the_first_object_planned_for_a_free_identifier() -> None:
    turns = Turns()
    awaiting = [(0, (0, 100)), (1, (0, 2)), (2, (0, 90))]
    order = turns.plan(2, awaiting, 0.0, identifier_pace([paper_team()["spot"]], 1.0))
    # neither identifier's place is known: the two oldest
    assert [turns.may_start(k, order) for k in range(3)] == [True, True, False]
    turns.started(0, (0, 100), order)
    turns.started(1, (0, 2), order)
    assert turns.order([]) == [0, 1]
    turns.free(0)  # the one at (0, 100) is free: object 2 is near it
    order = turns.plan(2, [(2, (0, 90))], 1.0, identifier_pace([paper_team()["spot"]], 1.0))
    assert turns.may_start(2, order)
    turns.ended(set())  # the other lane failed: both free
    assert all(r.busy is None for r in turns.robots)


def test_the_pace_is_the_quickest_identifiers() -> None:
    team = paper_team()
    pace = identifier_pace([team["husky"], team["spot"], team["bebop"]], 0.5)
    assert (pace.speed, pace.op_s) == (team["spot"].speed_mps / 0.5, 2.0)


def test_identifiers_that_carry_are_routed_nearest_first_however_long_objects_waited() -> None:
    # Huskies identify and carry: every object waits on them, and a cap would send one
    # across the cave to the oldest object (the far one) before the one beside it
    team = paper_team()
    husky = identifier_pace([team["husky"], team["bebop"]], 1.0)
    spot = identifier_pace([team["husky"], team["spot"], team["bebop"]], 1.0)
    assert husky.carry
    assert not spot.carry
    awaiting = [(0, (0, 100)), (1, (0, 2))]
    for pace, first in ((husky, 1), (spot, 0)):
        turns = Turns()
        turns.listed([0, 1], 0.0)  # the far one listed first
        turns.plan(1, awaiting, 0.0, pace)
        turns.started(9, (0, 0), [(9, 0)])  # the identifier stands at (0, 0)
        turns.free(9)
        order = turns.plan(1, awaiting, 300.0, pace)  # both waited 300 s
        assert order[0][0] == first
