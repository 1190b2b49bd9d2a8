"""The shared mission state (sans-IO): exploration, claims, and nothing lost or done twice."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from btcap.sim import GridMap
from btcap.sim.world.messages import Claim, ClaimReply
from btcap.sim.world.store import MissionState, ObjectStore, SimObject

# A 5 x 30 corridor: start on the left, decontamination area on the right.
CORRIDOR = GridMap.from_array(np.ones((5, 30), dtype=bool), start=(2, 0), decon_area=(2, 29))
# Two rooms joined by a one-cell door; a walled-off pocket nobody can reach.
ROOMS = GridMap.from_array(
    np.array(
        [
            [1, 1, 1, 1, 0, 1, 1, 1, 0, 1],
            [1, 1, 1, 1, 0, 1, 1, 1, 0, 1],
            [1, 1, 1, 1, 1, 1, 1, 1, 0, 0],
            [1, 1, 1, 1, 0, 1, 1, 1, 0, 1],
        ],
        dtype=bool,
    ),
    start=(0, 0),
    decon_area=(3, 7),
)


def state_with(grid: GridMap, cells: list[tuple[int, int]], dirty: list[bool]) -> MissionState:
    objs = [SimObject(i, c, d) for i, (c, d) in enumerate(zip(cells, dirty, strict=True))]
    return MissionState(grid, objs)


def explore_all(state: MissionState, radius_m: float, claimant: str = "x") -> int:
    """Claim and explore goals until the store says done; returns how many were explored."""
    n = 0
    while (reply := state.claim(claimant, "goal")).status == "ok":
        state.explore(reply.at, radius_m)
        n += 1
        assert n < 1000, "exploration does not end"
    assert reply.status == "done"
    return n


# -- exploration ----------------------------------------------------------------------------


def test_start_is_the_first_goal_and_nothing_is_covered() -> None:
    s = state_with(CORRIDOR, [(2, 3)], [True])
    assert [g.cell for g in s.pending_goals()] == [CORRIDOR.start]
    assert s.coverage == 0.0
    assert not s.exploration_complete
    assert not s.frontier().any()


def test_explore_reveals_objects_within_the_radius_only() -> None:
    s = state_with(CORRIDOR, [(2, 3), (2, 5), (2, 20)], [True, False, True])
    found = s.explore((2, 0), 4.0)
    assert found == 1
    assert [o.found for o in s.objects] == [True, False, False]
    # Exploring the same disc again finds nothing new.
    assert s.explore((2, 0), 4.0) == 0


def test_explore_adds_frontier_goals_outside_the_disc() -> None:
    s = state_with(CORRIDOR, [], [])
    s.explore((2, 0), 4.0)
    new = [g for g in s.pending_goals() if g.cell != CORRIDOR.start]
    assert new
    for g in new:
        assert s.frontier()[g.cell]
        assert not s.covered[g.cell]
        assert (g.cell[0] - 2) ** 2 + g.cell[1] ** 2 > 16


def test_explore_respects_cell_size() -> None:
    coarse = GridMap.from_array(
        np.ones((5, 30), dtype=bool), start=(2, 0), decon_area=(2, 29), cell_size_m=2.0
    )
    s = state_with(coarse, [(2, 3), (2, 5)], [True, True])
    assert s.explore((2, 0), 8.0) == 1  # 8 m is 4 cells


def test_unclaimed_goals_that_get_covered_are_done() -> None:
    s = state_with(CORRIDOR, [], [])
    s.explore((2, 0), 4.0)
    (goal,) = [g for g in s.pending_goals() if g.cell != CORRIDOR.start]
    s.explore(goal.cell, 4.0)
    assert goal.done


def test_coverage_grows_to_one_and_exploration_completes() -> None:
    s = state_with(ROOMS, [(0, 7), (3, 2)], [True, False])
    seen = [s.coverage]
    while (reply := s.claim("x", "goal")).status == "ok":
        s.explore(reply.at, 2.0)
        seen.append(s.coverage)
        assert len(seen) < 200
    assert reply.status == "done"
    assert seen == sorted(seen)
    assert s.coverage == 1.0
    assert s.exploration_complete
    assert not s.frontier().any()
    assert all(o.found for o in s.objects)
    # The unreachable pocket (column 9) is never covered and never a goal.
    assert not s.covered[:, 9].any()
    assert all(g.cell[1] != 9 for g in s.goals.values())


@pytest.mark.parametrize("radius_m", [1.0, 1.5, 3.0, 15.0])
def test_exploration_completes_for_any_radius(radius_m: float) -> None:
    grid = GridMap.generate_cave(30, 20, seed=3)
    s = MissionState.scatter(grid, 5, 0.5, np.random.default_rng(0))
    explore_all(s, radius_m)
    assert s.coverage == 1.0
    assert s.exploration_complete


def test_small_radius_goal_covered_while_claimed_does_not_orphan_the_frontier() -> None:
    """A claimed goal covered by someone else's explore must not stand for the frontier."""
    s = state_with(CORRIDOR, [], [])
    a = s.claim("a", "goal")
    assert a.status == "ok"
    # a's goal gets covered by a small disc while a still holds it.
    s.explore(a.at, 1.0)
    s.release("a")
    assert s.goals[a.target].done
    # Whoever claims next must find work while there is still a frontier.
    assert s.frontier().any()
    assert s.claim("b", "goal").status == "ok"
    explore_all(s, 1.5, "b")
    assert s.coverage == 1.0


# -- claims ---------------------------------------------------------------------------------


def found_state() -> MissionState:
    s = state_with(CORRIDOR, [(2, 1), (2, 2), (2, 3)], [True, False, True])
    s.explore((2, 0), 4.0)
    assert all(o.found for o in s.objects)
    return s


def test_objects_are_not_offered_before_they_are_found() -> None:
    s = state_with(CORRIDOR, [(2, 20)], [True])
    assert s.claim("a", "object") == ClaimReply("wait")
    s.explore((2, 20), 2.0)
    reply = s.claim("a", "object")
    assert (reply.status, reply.target, reply.at, reply.identified) == ("ok", 0, (2, 20), False)


def test_one_claim_per_claimant_and_never_twice_the_same_object() -> None:
    s = found_state()
    got = [s.claim(c, "object") for c in ("a", "b", "c")]
    assert sorted(r.target for r in got) == [0, 1, 2]
    assert s.claim("d", "object").status == "wait"  # all taken, not finished
    assert s.claims == {c: ("object", r.target) for c, r in zip("abc", got, strict=True)}
    for r, c in zip(got, "abc", strict=True):
        assert s.objects[r.target].claimed_by == c


def test_claiming_again_releases_the_previous_claim() -> None:
    s = found_state()
    first = s.claim("a", "object")
    second = s.claim("b", "object")
    assert s.claim("a", "goal").status == "ok"  # a's object is released, unfinished
    assert s.objects[first.target].claimed_by is None
    third = s.claim("c", "object")
    assert third.target == first.target
    # Claiming an object again may return the same one (a retry), never a second one.
    assert s.claim("b", "object").status == "ok"
    assert [o.id for o in s.objects if o.claimed_by == "b"] == [s.claims["b"][1]]
    assert second.target in {o.id for o in s.objects if o.claimed_by in (None, "b")}


def test_goal_and_object_claims_of_one_claimant_replace_each_other() -> None:
    s = found_state()
    obj = s.claim("a", "object")
    s.claim("a", "goal")
    assert s.objects[obj.target].claimed_by is None
    assert s.claims["a"][0] == "goal"


def test_finished_objects_are_not_offered_again() -> None:
    s = found_state()
    seen: dict[int, int] = {}
    for _ in range(10):
        reply = s.claim("a", "object")
        if reply.status != "ok":
            break
        seen[reply.target] = seen.get(reply.target, 0) + 1
        if s.identify(reply.target):
            s.pick_up(reply.target, "robot")
            s.decontaminated(reply.target)
    assert seen == {0: 1, 1: 1, 2: 1}
    explore_all(s, 40.0)
    assert s.claim("a", "object").status == "done"
    assert s.mission_complete
    assert all(o.cell == CORRIDOR.decon_area for o in s.objects if o.decontaminated)
    assert [o.decontaminated for o in s.objects] == [True, False, True]


def test_identified_objects_are_offered_with_their_identification() -> None:
    s = found_state()
    r = s.claim("a", "object")
    assert not r.identified
    s.identify(r.target)
    s.release("a")
    again = s.claim("b", "object")
    assert again.target == r.target  # the first available object comes first
    assert again.identified


def test_a_failed_carriers_object_is_offered_again_where_it_fell() -> None:
    s = found_state()
    r = s.claim("a", "object")
    assert s.identify(r.target)
    s.pick_up(r.target, "husky1")
    # Carried: not available even after its claimant lets go.
    s.release("a")
    assert s.objects[r.target].carried_by == "husky1"
    assert r.target not in {s.claim(c, "object").target for c in ("b", "c")}
    s.release("b")
    s.release("c")
    s.drop(r.target, (3, 9))
    again = [s.claim(c, "object") for c in ("d", "e", "f")]
    mine = next(x for x in again if x.target == r.target)
    assert mine.at == (3, 9)
    assert mine.identified


def test_done_only_when_explored_and_every_found_object_finished() -> None:
    s = found_state()
    for o in s.objects:
        s.identify(o.id)
        if o.contaminated:
            s.decontaminated(o.id)
    # Not explored yet: objects may still turn up.
    assert s.claim("a", "object").status == "wait"
    explore_all(s, 40.0)
    assert s.claim("a", "object").status == "done"
    assert s.claim("a", "goal").status == "done"


def test_goal_claims_wait_while_another_claimant_explores() -> None:
    s = state_with(CORRIDOR, [], [])
    assert s.claim("a", "goal").status == "ok"
    assert s.claim("b", "goal").status == "wait"  # a's goal may open a frontier
    s.release("a")  # released unexplored: offered again
    reply = s.claim("b", "goal")
    assert (reply.status, reply.at) == ("ok", CORRIDOR.start)


def test_goal_done_releases_its_claim() -> None:
    s = state_with(CORRIDOR, [], [])
    reply = s.claim("a", "goal")
    s.goal_done(reply.target)
    assert "a" not in s.claims
    assert s.goals[reply.target].done


def test_unknown_claim_kind() -> None:
    s = state_with(CORRIDOR, [], [])
    with pytest.raises(ValueError, match="claim kind"):
        s.claim("a", "nothing")
    assert ObjectStore(s).on_claim(Claim("a", "nothing")) == ClaimReply("done")


def test_summary_counts() -> None:
    s = found_state()
    s.identify(0)
    s.decontaminated(0)
    s.identify(1)
    assert s.summary() == {
        "objects": 3,
        "found": 3,
        "identified": 2,
        "contaminated": 1,
        "decontaminated": 1,
        "goals": len(s.goals),
        "coverage": round(s.coverage, 4),
    }


def test_scatter_is_deterministic_per_seed() -> None:
    grid = GridMap.generate_cave(30, 20, seed=3)

    def placed(seed: int) -> list[tuple[tuple[int, int], bool]]:
        s = MissionState.scatter(grid, 8, 0.5, np.random.default_rng(seed))
        return [(o.cell, o.contaminated) for o in s.objects]

    assert placed(4) == placed(4)
    assert placed(4) != placed(5)
    assert all(grid.reachable[c] for c, _ in placed(4))


# -- property: nothing lost, nothing doubled ------------------------------------------------

CLAIMANTS = ("a", "b", "c")
OPS = st.lists(
    st.tuples(
        st.sampled_from(["claim_goal", "claim_object", "release", "explore", "work", "drop"]),
        st.sampled_from(CLAIMANTS),
        st.integers(0, 10_000),
        st.sampled_from([1.0, 1.5, 2.0, 4.0]),
    ),
    max_size=40,
)


def check_consistent(s: MissionState, n_objects: int) -> None:
    assert [o.id for o in s.objects] == list(range(n_objects))
    held = {}
    for claimant, (kind, ident) in s.claims.items():
        item = s.goals[ident] if kind == "goal" else s.objects[ident]
        assert item.claimed_by == claimant
        held[(kind, ident)] = claimant
    for g in s.goals.values():
        if g.claimed_by is not None:
            assert held[("goal", g.id)] == g.claimed_by
            assert not g.done
    for o in s.objects:
        if o.claimed_by is not None:
            assert held[("object", o.id)] == o.claimed_by
        assert s.grid.reachable[o.cell]
        if o.decontaminated:
            assert o.contaminated
            assert o.carried_by is None
            assert o.cell == s.grid.decon_area
        if o.carried_by is not None:
            assert o.found
            assert o.identified
            assert not o.decontaminated


@settings(max_examples=60)
@given(seed=st.integers(0, 1000), ops=OPS)
def test_random_claims_lose_and_double_nothing(
    seed: int, ops: list[tuple[str, str, int, float]]
) -> None:
    grid = GridMap.generate_cave(24, 16, seed=seed % 5)
    n = 6
    s = MissionState.scatter(grid, n, 0.5, np.random.default_rng(seed))
    reachable = np.argwhere(grid.reachable)
    for op, who, pick, radius in ops:
        others = {c: held for c, held in s.claims.items() if c != who}
        if op in ("claim_goal", "claim_object"):
            kind = "goal" if op == "claim_goal" else "object"
            reply = s.claim(who, kind)
            if reply.status == "ok":
                assert (kind, reply.target) not in others.values()
                assert s.claims[who] == (kind, reply.target)
        elif op == "release":
            s.release(who)
        elif op == "explore":
            held = s.claims.get(who)
            if held is not None and held[0] == "goal":
                cell = s.goals[held[1]].cell
            else:
                r, c = reachable[pick % len(reachable)]
                cell = (int(r), int(c))
            s.explore(cell, radius)
        elif op == "work":  # identify, then pick up or finish decontaminating
            held = s.claims.get(who)
            if held is not None and held[0] == "object":
                o = s.objects[held[1]]
                if o.identified is None:
                    s.identify(o.id)
                elif o.identified and o.carried_by is None:
                    s.pick_up(o.id, who)
                elif o.carried_by == who:
                    s.decontaminated(o.id)
        elif op == "drop":  # whatever ``who`` carries falls where a random cell is
            for o in s.objects:
                if o.carried_by == who:
                    r, c = reachable[pick % len(reachable)]
                    s.drop(o.id, (int(r), int(c)))
        check_consistent(s, n)

    # Everyone lets go (carriers fail): then the rest of the mission can still be done.
    for who in CLAIMANTS:
        s.release(who)
        for o in s.objects:
            if o.carried_by == who:
                s.drop(o.id, o.cell)
    check_consistent(s, n)
    for _ in range(500):
        goal = s.claim("explorer", "goal")
        if goal.status == "ok":
            s.explore(goal.at, 1.5)
        obj = s.claim("worker", "object")
        if obj.status == "ok" and s.identify(obj.target):
            s.pick_up(obj.target, "worker")
            s.decontaminated(obj.target)
        check_consistent(s, n)
        # Nobody else holds anything, so "wait" would mean the mission is stuck.
        assert goal.status != "wait"
        if goal.status == "done" and obj.status != "ok":
            break
    assert s.claim("worker", "object").status == "done"
    assert s.mission_complete
    assert s.coverage == 1.0
    assert all(o.found for o in s.objects)
    assert all(o.decontaminated == o.contaminated for o in s.objects)


def test_work_lists_give_the_oldest_news_first() -> None:
    # Object 0 lies far, object 1 near the start: found 1 then 0, so identified in that
    # order (object ids are the scatter's, no order of the mission's); carried in the
    # order they were identified. A list by id left object 1 waiting behind 0.
    s = state_with(CORRIDOR, [(2, 25), (2, 3), (2, 12)], [True, True, False])
    s.explore((2, 0), 4.0)
    s.explore((2, 12), 4.0)
    s.explore((2, 25), 4.0)
    assert [i[0] for i in s.work_list("identify").items] == [1, 2, 0]
    s.identify(1)
    s.identify(0)
    assert [i[0] for i in s.work_list("carry").items] == [1, 0]


def test_the_object_list_holds_each_object_with_its_work_left() -> None:
    # One list for the pool mission's object lanes: an object awaiting identification
    # (flag 0), then, once known contaminated, to carry (flag 1); gone once clean or
    # decontaminated.
    s = state_with(CORRIDOR, [(2, 25), (2, 3), (2, 12)], [True, True, False])
    s.explore((2, 0), 4.0)
    s.explore((2, 12), 4.0)
    assert s.work_list("object").items == [(1, 2, 3, 0), (2, 2, 12, 0)]
    assert not s.work_list("object").complete
    s.identify(1)
    s.identify(2)
    assert s.work_list("object").items == [(1, 2, 3, 1)]
    s.pick_up(1, "husky")
    s.drop(1, (2, 5))
    assert s.work_list("object").items == [(1, 2, 5, 1)]  # where it fell
    s.explore((2, 25), 4.0)
    s.identify(0)
    s.decontaminated(1)
    s.decontaminated(0)
    listed = s.work_list("object")
    assert listed.items == []
    assert listed.complete == s.exploration_complete


def test_every_change_of_an_objects_picture_is_counted() -> None:
    """The monitor's world feed reads the objects only when the state counts a change."""
    s = state_with(CORRIDOR, [(2, 3), (2, 20)], [True, True])
    counted = [s.changes]
    s.explore((2, 0), 4.0)  # finds object 0
    s.explore((2, 0), 4.0)  # finds nothing new
    counted.append(s.changes)
    s.identify(0)
    counted.append(s.changes)
    s.pick_up(0, "husky1")
    counted.append(s.changes)
    s.drop(0, (2, 10))
    counted.append(s.changes)
    s.pick_up(0, "husky1")
    s.decontaminated(0)
    counted.append(s.changes)
    assert counted == [0, 1, 2, 3, 4, 6]
