"""The consensus core on explicit inputs: robots exchange messages only through the
helpers below, in synchronous rounds or in any order a test (or hypothesis) chooses."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from btcap.team.core.consensus import Claim, Consensus, Task, Vector
from btcap.team.ids import ExecutionId

ORIGIN = "o"


def tid(j: int) -> ExecutionId:
    return ExecutionId(ORIGIN, f"t{j}", j)


@dataclass(frozen=True)
class Msg:
    sender: str
    seq: int
    claim: Claim
    view: Vector
    version: int
    tasks: tuple[Task[None], ...]


@dataclass
class Robot:
    cons: Consensus[None]
    costs: dict[ExecutionId, float] = field(default_factory=dict)
    seq: int = 0
    said: tuple[Claim, Vector] | None = None

    def speak(self) -> Msg | None:
        """Select, then a message if the claim or what it merged changed since it spoke."""
        c = self.cons
        c.select({t: v for t, v in self.costs.items() if t in c.tasks()})
        now = (c.claim, c.vector())
        if now == self.said:
            return None
        self.said = now
        self.seq += 1
        return Msg(c.robot, self.seq, c.claim, now[1], c.version, tuple(c.own_tasks()))

    def receive(self, m: Msg) -> None:
        self.cons.offer(m.sender, m.version, m.tasks)
        self.cons.hear(m.sender, m.seq, m.claim, m.view)


class Team:
    def __init__(self, costs: Mapping[str, Mapping[int, float]], tasks: int) -> None:
        names = [ORIGIN, *costs]
        self.robots = {r: Robot(Consensus(r)) for r in names}
        for r in self.robots.values():
            for other in names:
                r.cons.join(other)
            r.costs = {tid(j): c for j, c in costs.get(r.cons.robot, {}).items()}
        origin = self.robots[ORIGIN].cons
        for j in range(tasks):
            origin.open(Task(tid(j), frozenset(costs), None))
        self.messages = 0

    def round(self) -> bool:
        """Everyone selects and speaks, everyone hears everyone; False when all were quiet."""
        said = [m for r in self.robots.values() if (m := r.speak()) is not None]
        for m in said:
            for r in self.robots.values():
                if r.cons.robot != m.sender:
                    r.receive(m)
                    self.messages += 1
        return bool(said)

    def run(self, limit: int = 200) -> int:
        for n in range(1, limit + 1):
            if not self.round():
                return n
        raise AssertionError("no convergence")

    def assignment(self) -> dict[ExecutionId, str]:
        return {t: c.robot for t, c in self.robots[ORIGIN].cons.winners().items()}

    def lose(self, robot: str) -> None:
        del self.robots[robot]
        for r in self.robots.values():
            r.cons.lose(robot)


def greedy(costs: Mapping[str, Mapping[int, float]]) -> dict[ExecutionId, str]:
    """Sequential single-item: the cheapest (cost, robot, task) pair first, then the next."""
    pairs = sorted((c, r, str(tid(j)), j) for r, by in costs.items() for j, c in by.items())
    out: dict[ExecutionId, str] = {}
    for _c, r, _s, j in pairs:
        if tid(j) not in out and r not in out.values():
            out[tid(j)] = r
    return out


def agreed(t: Team) -> None:
    """Every robot converged on the same conflict-free assignment."""
    views = {r: tuple(sorted(c.winners().items(), key=str)) for r, c in _cons(t).items()}
    assert len(set(views.values())) == 1, views
    assert all(c.converged() for c in _cons(t).values())
    winners = list(t.assignment().values())
    assert len(winners) == len(set(winners))
    for robot, c in _cons(t).items():
        mine = c.claim
        if mine.task is not None:
            assert t.assignment()[mine.task] == robot


def _cons(t: Team) -> dict[str, Consensus[None]]:
    return {r: x.cons for r, x in t.robots.items()}


# -- convergence and quality ---------------------------------------------------------------


def test_the_classic_greedy_trap_converges_to_the_greedy_result() -> None:
    costs = {"b": {1: 1.0, 2: 2.0}, "c": {1: 2.0, 2: 100.0}}
    t = Team(costs, 3)
    t.run()
    agreed(t)
    assert t.assignment() == {tid(1): "b", tid(2): "c"} == greedy(costs)


def test_more_tasks_than_robots_leaves_the_dearest_open() -> None:
    costs = {"a": {0: 3.0, 1: 1.0, 2: 2.0}}
    t = Team(costs, 3)
    t.run()
    agreed(t)
    assert t.assignment() == {tid(1): "a"}


def test_equal_bids_go_to_the_lower_robot_id() -> None:
    t = Team({"c": {0: 2.0}, "b": {0: 2.0}, "d": {0: 2.0}}, 1)
    t.run()
    assert t.assignment() == {tid(0): "b"}


def test_nobody_converges_before_every_member_has_spoken() -> None:
    t = Team({"a": {0: 1.0}, "b": {0: 2.0}}, 1)
    t.round()
    assert not any(c.converged() for c in _cons(t).values())
    assert t.robots[ORIGIN].cons.waiting_for()


costs_st = st.dictionaries(
    st.sampled_from("abcdefgh"),
    st.dictionaries(st.integers(0, 5), st.integers(1, 6).map(float), max_size=6),
    min_size=1,
)


@given(costs_st)
@settings(max_examples=60, deadline=None)
def test_synchronous_rounds_equal_sequential_greedy(costs: dict[str, dict[int, float]]) -> None:
    t = Team(costs, 6)
    rounds = t.run()
    agreed(t)
    assert t.assignment() == greedy(costs)
    assert rounds <= 2 * 6 + 3  # CBAA: at most one task settles per round, plus the views


@given(costs_st, st.randoms(use_true_random=False), st.integers(0, 3))
@settings(max_examples=60, deadline=None)
def test_any_order_and_repeats_reach_the_same_result(
    costs: dict[str, dict[int, float]], rnd: object, dup: int
) -> None:
    """Messages delivered in a random order, some of them several times, some robots
    acting on stale news: the same greedy assignment once everything is delivered."""
    import random

    assert isinstance(rnd, random.Random)
    t = Team(costs, 6)
    pool: list[tuple[str, Msg]] = []
    for _ in range(400):
        for r in t.robots.values():
            if rnd.random() < 0.5 and (m := r.speak()) is not None:
                pool += [(d, m) for d in t.robots if d != m.sender] * (1 + rnd.randint(0, dup))
        if not pool:
            break
        for _ in range(rnd.randint(1, len(pool))):
            dest, m = pool.pop(rnd.randrange(len(pool)))
            t.robots[dest].receive(m)
    # then rounds on reliable delivery (stale copies still around are harmless)
    for dest, m in pool:
        t.robots[dest].receive(m)
    t.run()
    agreed(t)
    assert t.assignment() == greedy(costs)


# -- change and failure ------------------------------------------------------------------


def test_a_robot_lost_mid_consensus_has_its_task_reallocated() -> None:
    costs = {"a": {0: 1.0, 1: 5.0}, "b": {0: 2.0, 1: 3.0}, "c": {0: 4.0, 1: 4.0}}
    t = Team(costs, 2)
    t.round()
    t.round()  # "a" has claimed task 0 and been heard, nothing has settled everywhere yet
    assert t.robots["b"].cons.winners()[tid(0)].robot == "a"
    t.lose("a")
    t.run()
    agreed(t)
    assert t.assignment() == {tid(0): "b", tid(1): "c"}
    assert "a" not in t.robots[ORIGIN].cons.vector()


def test_a_closed_task_frees_its_winner_for_the_next() -> None:
    costs = {"a": {0: 1.0, 1: 2.0}, "b": {0: 2.0, 1: 5.0}}
    t = Team(costs, 2)
    t.run()
    assert t.assignment() == {tid(0): "a", tid(1): "b"}
    t.robots[ORIGIN].cons.close(tid(0))  # awarded to "a", who is busy from now on
    t.robots["a"].costs = {}
    t.robots["b"].costs = {tid(1): 5.0}
    t.run()
    agreed(t)
    assert t.assignment() == {tid(1): "b"}


def test_a_robot_that_declined_the_award_is_no_longer_a_candidate() -> None:
    t = Team({"a": {0: 1.0}, "b": {0: 2.0}}, 1)
    t.run()
    t.robots[ORIGIN].cons.restrict(tid(0), "a")
    t.run()
    agreed(t)
    assert t.assignment() == {tid(0): "b"}


# -- who may say what ---------------------------------------------------------------------


def test_a_robot_speaks_only_for_itself() -> None:
    c: Consensus[None] = Consensus("o")
    c.join("a")
    c.join("m")
    c.open(Task(tid(0), frozenset({"a", "m"}), None))
    assert not c.hear("m", 1, Claim("a", 5, tid(0), 0.0), {})  # "m" claiming for "a"
    assert not c.hear("m", 1, Claim("m", 1, tid(0), -1.0), {})
    assert not c.hear("m", 1, Claim("m", 1, tid(0), math.nan), {})
    assert not c.hear("x", 1, Claim("x", 1, tid(0), 0.0), {})  # not a member: not kept
    assert c.refused == 3
    assert c.winners() == {}
    forged = Task(ExecutionId("a", "t", 9), frozenset({"m"}), None)
    assert c.offer("m", 1, [forged])  # tasks of another origin are not taken from it
    assert c.tasks().keys() == {tid(0)}
    assert c.refused == 4
    with pytest.raises(ValueError, match="only its origin"):
        c.open(forged)


def test_a_claim_on_a_task_it_is_no_candidate_for_wins_nothing() -> None:
    c: Consensus[None] = Consensus("o")
    c.join("x")
    c.open(Task(tid(0), frozenset({"a"}), None))
    assert c.hear("x", 1, Claim("x", 1, tid(0), 0.0), {})
    assert c.winners() == {}


def test_old_and_repeated_messages_change_nothing() -> None:
    c: Consensus[None] = Consensus("o")
    c.join("a")
    c.open(Task(tid(0), frozenset({"a"}), None))
    assert c.hear("a", 2, Claim("a", 2, tid(0), 1.0), {})
    assert not c.hear("a", 1, Claim("a", 1), {})  # overtaken
    assert not c.hear("a", 2, Claim("a", 2, tid(0), 1.0), {})  # repeated
    assert c.winners()[tid(0)].robot == "a"


def test_a_peer_flooding_task_ids_is_held_to_the_bound() -> None:
    c: Consensus[None] = Consensus("o", max_tasks=8, max_members=4)
    c.join("h")
    flood = [Task(ExecutionId("h", "n", i), frozenset({"o"}), None) for i in range(10_000)]
    assert c.offer("h", 1, flood)
    assert len(c.tasks()) == 8
    assert c.dropped == 10_000 - 8
    view = {f"ghost{i}": (1, 1) for i in range(1000)}
    assert c.hear("h", 1, Claim("h", 1), view)
    assert c.views["h"] == {}
    for i in range(10):
        c.join(f"r{i}")
    assert len(c.members) == 4
    assert not c.offer("h", 1, flood)  # the same version again: nothing new kept


def test_a_lost_robot_that_comes_back_starts_afresh() -> None:
    c: Consensus[None] = Consensus("o")
    c.join("a")
    c.open(Task(tid(0), frozenset({"a"}), None))
    c.hear("a", 7, Claim("a", 7, tid(0), 1.0), {})
    c.lose("a")
    assert not c.hear("a", 8, Claim("a", 8, tid(0), 1.0), {})  # not a member now
    c.join("a")
    assert c.hear("a", 1, Claim("a", 1, tid(0), 2.0), {})  # restarted: numbers from 1
    assert c.winners()[tid(0)].cost == 2.0


def test_the_tasks_of_a_lost_origin_go_with_it() -> None:
    """Robot "a" wins origin p's task; p is lost: a's claim falls back to o's task."""
    t = Team({"a": {0: 2.0}}, 1)
    t.robots["p"] = Robot(Consensus("p"))
    for r in t.robots.values():
        for other in t.robots:
            r.cons.join(other)
    task = Task(ExecutionId("p", "t", 1), frozenset({"a"}), None)
    t.robots["p"].cons.open(task)
    t.robots["a"].costs[task.id] = 1.0
    t.run()
    agreed(t)
    assert t.robots["a"].cons.claim.task == task.id
    t.lose("p")
    t.run()
    agreed(t)
    assert t.robots["a"].cons.claim.task == tid(0)
    assert task.id not in t.robots[ORIGIN].cons.tasks()
