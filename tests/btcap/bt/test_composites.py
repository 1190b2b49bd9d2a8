"""Control flow: every Sequence and Fallback, Parallel, IfThenElse, Switch.

Every tick goes through ``tick_checked``: after each one, no node may be left active
unless it was ticked (the halting invariant).
"""

from __future__ import annotations

import asyncio

import anyio
import pytest
from structlog.testing import capture_logs

from btcap import (
    Action,
    AlwaysFailure,
    AlwaysRunning,
    AlwaysSuccess,
    Condition,
    Constant,
    Fallback,
    IfThenElse,
    Leaf,
    Node,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Repeat,
    RestartLoopWarning,
    Sequence,
    SequenceWithMemory,
    State,
    Switch,
    Tree,
    TreeError,
    TreeTimeout,
    Wait,
    loads_tree,
)
from btcap.actors import ManualClock
from btcap.bt.invariants import tick_checked as tick

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING
WAITING = [State.RUNNING, State.UNASSIGNED, State.ASSIGNED, State.PAUSED]


class Leafy(Leaf):
    """Returns ``result`` (settable; an exception is raised instead) and counts ticks."""

    def __init__(self, name: str, result: State | Exception = S) -> None:
        super().__init__(name)
        self.result = result
        self.ticks = 0
        self.unticks = 0

    def on_tick(self) -> State:
        self.ticks += 1
        if isinstance(self.result, Exception):
            raise self.result
        return self.result

    def on_untick(self) -> None:
        self.unticks += 1


def leaves(*results: State) -> list[Leafy]:
    return [Leafy(f"c{i}", r) for i, r in enumerate(results)]


def ticks(nodes: list[Leafy]) -> list[int]:
    return [n.ticks for n in nodes]


def states(nodes: list[Leafy]) -> list[State]:
    return [n.state for n in nodes]


async def settle() -> None:
    for _ in range(5):
        await asyncio.sleep(0)


# -- all Sequences and Fallbacks: one tick ---------------------------------------------

SEQUENCES = [Sequence, SequenceWithMemory, ReactiveSequence]
FALLBACKS = [Fallback, ReactiveFallback]


@pytest.mark.parametrize("kind", SEQUENCES)
@pytest.mark.parametrize(
    ("results", "expected", "ticked"),
    [
        ([S, S, S], S, [1, 1, 1]),
        ([S, F, S], F, [1, 1, 0]),
        ([S, R, S], R, [1, 1, 0]),
        ([F, S, S], F, [1, 0, 0]),
        ([], S, []),
    ],
)
def test_sequence_results(
    kind: type[Node], results: list[State], expected: State, ticked: list[int]
) -> None:
    kids = leaves(*results)
    tree = Tree(kind("seq", children=kids))
    assert tick(tree) is expected
    assert ticks(kids) == ticked


@pytest.mark.parametrize("kind", FALLBACKS)
@pytest.mark.parametrize(
    ("results", "expected", "ticked"),
    [
        ([F, F, F], F, [1, 1, 1]),
        ([F, S, F], S, [1, 1, 0]),
        ([F, R, F], R, [1, 1, 0]),
        ([S, F, F], S, [1, 0, 0]),
        ([], F, []),
    ],
)
def test_fallback_results(
    kind: type[Node], results: list[State], expected: State, ticked: list[int]
) -> None:
    kids = leaves(*results)
    tree = Tree(kind("fb", children=kids))
    assert tick(tree) is expected
    assert ticks(kids) == ticked


@pytest.mark.parametrize("kind", SEQUENCES + FALLBACKS)
@pytest.mark.parametrize("waiting", WAITING)
def test_waiting_children_count_as_running(kind: type[Node], waiting: State) -> None:
    first = F if kind in FALLBACKS else S
    kids = leaves(first, waiting, first)
    tree = Tree(kind("c", children=kids))
    assert tick(tree) is R
    assert kids[1].state is waiting
    assert ticks(kids) == [1, 1, 0]


@pytest.mark.parametrize("kind", SEQUENCES + FALLBACKS)
def test_error_child_counts_as_failed_and_keeps_its_error(kind: type[Node]) -> None:
    bad = Leafy("bad", ValueError("boom"))
    after = Leafy("after", S)
    tree = Tree(kind("c", children=[bad, after]))
    with capture_logs():
        result = tick(tree)
    assert bad.state is State.ERROR
    assert isinstance(bad.error, ValueError)
    if kind in FALLBACKS:
        assert (result, after.ticks) == (S, 1)
    else:
        assert (result, after.ticks) == (F, 0)


# -- ReactiveSequence, ReactiveFallback: from the first child every tick --------------------


@pytest.mark.parametrize("kind", [ReactiveSequence, ReactiveFallback])
def test_reactive_composites_retick_from_the_first_child(kind: type[Node]) -> None:
    first = S if kind is ReactiveSequence else F
    kids = leaves(first, first, R)
    tree = Tree(kind("c", children=kids))
    for _ in range(3):
        assert tick(tree) is R
    assert ticks(kids) == [3, 3, 3]


@pytest.mark.parametrize("kind", [ReactiveSequence, ReactiveFallback])
@pytest.mark.parametrize("waiting", [State.RUNNING, State.UNASSIGNED, State.ASSIGNED])
def test_earlier_child_running_unticks_the_later_running_child(
    kind: type[Node], waiting: State
) -> None:
    first = S if kind is ReactiveSequence else F
    a, b, c = leaves(first, first, waiting)
    tree = Tree(kind("c", children=[a, b, c]))
    assert tick(tree) is R
    assert c.state is waiting
    b.result = R
    assert tick(tree) is R
    assert c.state is State.PAUSED
    assert c.unticks == 1
    assert b.state is R
    assert c.ticks == 1
    a.result = R
    assert tick(tree) is R
    assert b.state is State.PAUSED
    assert ticks([a, b, c]) == [3, 2, 1]


@pytest.mark.parametrize("kind", [ReactiveSequence, ReactiveFallback])
def test_earlier_child_finishing_unticks_the_later_running_child(kind: type[Node]) -> None:
    first, stop = (S, F) if kind is ReactiveSequence else (F, S)
    a, b = leaves(first, R)
    tree = Tree(kind("c", children=[a, b]))
    assert tick(tree) is R
    a.result = stop
    assert tick(tree) is stop
    assert b.state is State.PAUSED
    assert b.unticks == 1


def test_finished_later_children_are_not_unticked() -> None:
    a, b, c = leaves(S, S, S)
    tree = Tree(ReactiveSequence("seq", children=[a, b, c]))
    assert tick(tree) is S
    a.result = R
    assert tick(tree) is R
    assert [b.unticks, c.unticks] == [0, 0]
    assert states([b, c]) == [S, S]


async def test_preempted_action_is_paused_and_its_task_cancelled() -> None:
    with anyio.fail_after(5):
        seen: list[str] = []

        async def move() -> None:
            seen.append("started")
            try:
                await asyncio.sleep(100)
            except asyncio.CancelledError:
                seen.append("cancelled")
                raise

        guard = Leafy("guard", S)
        act = Action(move, "move")
        tree = Tree(ReactiveSequence("seq", children=[guard, act]))
        assert tick(tree) is R
        await settle()
        assert seen == ["started"]
        guard.result = R
        assert tick(tree) is R
        assert act.state is State.PAUSED
        await settle()
        assert seen == ["started", "cancelled"]
        await tree.shutdown()


# -- Sequence, Fallback: resume at the running child (BehaviorTree.CPP's) ----------------


def test_sequence_resumes_at_the_running_child() -> None:
    a, b, c = leaves(S, R, S)
    tree = Tree(Sequence("seq", children=[a, b, c]))
    assert tick(tree) is R
    assert tick(tree) is R
    assert ticks([a, b, c]) == [1, 2, 0]
    a.result = F  # no longer looked at
    b.result = S
    assert tick(tree) is S
    assert ticks([a, b, c]) == [1, 3, 1]
    assert tick(tree) is F  # a success starts over from the first child
    assert ticks([a, b, c]) == [2, 3, 1]


def test_sequence_failure_starts_over_at_the_first_child() -> None:
    a, b, c = leaves(S, R, S)
    tree = Tree(Sequence("seq", children=[a, b, c]))
    assert tick(tree) is R
    b.result = F
    assert tick(tree) is F
    assert ticks([a, b, c]) == [1, 2, 0]
    assert tick(tree) is F
    assert ticks([a, b, c]) == [2, 3, 0]


def test_fallback_resumes_at_the_running_child() -> None:
    a, b, c = leaves(F, R, S)
    tree = Tree(Fallback("fb", children=[a, b, c]))
    assert tick(tree) is R
    a.result = S  # no longer looked at
    assert tick(tree) is R
    assert ticks([a, b, c]) == [1, 2, 0]
    b.result = F
    assert tick(tree) is S
    assert ticks([a, b, c]) == [1, 3, 1]
    assert tick(tree) is S  # a success starts over from the first child
    assert ticks([a, b, c]) == [2, 3, 1]


def test_fallback_starts_over_when_every_child_failed() -> None:
    a, b = leaves(F, R)
    tree = Tree(Fallback("fb", children=[a, b]))
    assert tick(tree) is R
    b.result = F
    assert tick(tree) is F
    assert ticks([a, b]) == [1, 2]
    assert tick(tree) is F
    assert ticks([a, b]) == [2, 3]


@pytest.mark.parametrize("kind", [Sequence, SequenceWithMemory, Fallback])
def test_memory_resumes_after_untick_and_forgets_on_reset(kind: type[Node]) -> None:
    a, b = leaves(F if kind is Fallback else S, R)
    tree = Tree(kind("m", children=[a, b]))
    tick(tree)
    tree.untick()
    assert states([a, b]) == [a.result, State.PAUSED]
    tick(tree)
    assert ticks([a, b]) == [1, 2]
    tree.reset()
    tick(tree)
    assert ticks([a, b]) == [2, 3]


async def test_a_newcomers_first_tree_finishes() -> None:
    """A check, a repeated wait, then an action: the Sequence resumes at the action, where
    a ReactiveSequence restarts the finished Repeat every tick, halting the action."""
    clock = ManualClock()
    runs: list[str] = []

    async def act() -> None:
        runs.append("started")
        await clock.sleep(0.3)
        runs.append("done")

    def newcomer(kind: type[Node]) -> Tree:
        children = [
            Condition(lambda: True, "check"),
            Repeat("twice", times=2, children=[Wait("wait", seconds=0.2)]),
            Action(act, "act"),
        ]
        return Tree(kind("s", children=children), clock=clock)

    with anyio.fail_after(10):
        async with clock.autojump():
            tree = newcomer(Sequence)
            assert await tree.run(rate_hz=10, max_ticks=100) is S
            await tree.shutdown()
            assert runs == ["started", "done"]
            assert clock.now() < 2.0

            runs.clear()
            tree = newcomer(ReactiveSequence)
            with (
                pytest.warns(RestartLoopWarning, match="'s/act'.*use Sequence"),
                pytest.raises(TreeTimeout, match="still running"),  # 10 s later: still going
            ):
                await tree.run(rate_hz=10, max_ticks=100)
            await tree.shutdown()
            assert "done" not in runs
            assert len(runs) > 1  # the action was halted and started again


# -- SequenceWithMemory: also resumes at a child that failed (BehaviorTree.CPP's) ----------


def test_sequence_with_memory_resumes_at_the_failed_child() -> None:
    a, b, c = leaves(S, F, S)
    tree = Tree(SequenceWithMemory("swm", children=[a, b, c]))
    assert tick(tree) is F
    assert ticks([a, b, c]) == [1, 1, 0]
    assert tick(tree) is F  # the failed child again, not the first
    assert ticks([a, b, c]) == [1, 2, 0]
    b.result = S
    assert tick(tree) is S
    assert ticks([a, b, c]) == [1, 3, 1]
    assert tick(tree) is S  # a success starts over from the first child
    assert ticks([a, b, c]) == [2, 4, 2]


def test_sequence_with_memory_resumes_at_a_running_child_that_then_fails() -> None:
    a, b, c = leaves(S, R, S)
    tree = Tree(SequenceWithMemory("swm", children=[a, b, c]))
    assert tick(tree) is R
    b.result = F
    assert tick(tree) is F
    b.result = S
    assert tick(tree) is S
    assert ticks([a, b, c]) == [1, 3, 1]


def test_sequence_with_memory_resumes_at_a_child_in_error() -> None:
    a, b = leaves(S, S)
    bad = Leafy("bad", RuntimeError("x"))
    tree = Tree(SequenceWithMemory("swm", children=[a, bad, b]))
    with capture_logs():
        assert tick(tree) is F
        assert tick(tree) is F
    assert bad.state is State.ERROR
    assert ticks([a, bad, b]) == [1, 2, 0]
    bad.result = S
    assert tick(tree) is S
    assert ticks([a, bad, b]) == [1, 3, 1]


def test_sequence_with_memory_keeps_a_failure_across_untick_and_forgets_it_on_reset() -> None:
    a, b = leaves(S, F)
    tree = Tree(SequenceWithMemory("swm", children=[a, b]))
    assert tick(tree) is F
    tree.untick()
    assert tick(tree) is F
    assert ticks([a, b]) == [1, 2]
    tree.reset()
    assert tick(tree) is F
    assert ticks([a, b]) == [2, 3]


def test_sequence_with_memory_under_a_reactive_parent_keeps_its_place() -> None:
    """A parent that starts over leaves a finished child alone, as BehaviorTree.CPP's
    halt leaves SequenceWithMemory's index: the next run resumes at the failed child."""
    a, b = leaves(S, F)
    swm = SequenceWithMemory("swm", children=[a, b])
    tree = Tree(ReactiveFallback("root", children=[swm, Leafy("other", S)]))
    assert tick(tree) is S
    assert tick(tree) is S
    assert ticks([a, b]) == [1, 2]


# -- Parallel ---------------------------------------------------------------------------


def test_parallel_default_needs_every_child() -> None:
    a, b, c = leaves(S, R, R)
    tree = Tree(Parallel("par", children=[a, b, c]))
    assert tick(tree) is R
    b.result = S
    assert tick(tree) is R
    assert ticks([a, b, c]) == [1, 2, 2]  # finished children are not ticked again
    c.result = S
    assert tick(tree) is S
    assert ticks([a, b, c]) == [1, 2, 3]


def test_parallel_default_fails_as_soon_as_one_child_fails() -> None:
    a, b, c = leaves(R, F, R)
    tree = Tree(Parallel("par", children=[a, b, c]))
    assert tick(tree) is F
    assert states([a, b, c]) == [State.PAUSED, F, State.PAUSED]
    assert [a.unticks, c.unticks] == [1, 1]


@pytest.mark.parametrize(
    ("success", "failure", "results", "expected"),
    [
        (1, None, [R, S, R], S),
        (1, None, [F, F, R], R),  # success still possible
        (1, None, [F, F, F], F),
        (2, None, [F, R, R], R),
        (2, None, [F, F, R], F),  # success has become impossible
        (2, 1, [F, R, R], F),
        (-1, 3, [F, R, R], F),  # all must succeed: one failure makes that impossible
        (-2, None, [F, S, R], R),  # -2: all but one
        (-2, None, [F, S, S], S),
        (-1, None, [S, S, S], S),
        (0, None, [R, R, R], S),
        (1, 1, [F, S, R], F),  # both thresholds reached in one tick: failure wins
        (-1, 1, [S, F, S], F),
        (2, 3, [S, F, F], F),  # the reported loop: success impossible, so it fails
        (1, -1, [F, F, R], R),  # -1 failures: all of them
        (1, -1, [F, F, F], F),
        (3, 2, [S, S, S], S),
    ],
)
def test_parallel_thresholds(
    success: int, failure: int | None, results: list[State], expected: State
) -> None:
    kids = leaves(*results)
    par = Parallel("par", children=kids, success_threshold=success, failure_threshold=failure)
    tree = Tree(par)
    assert tick(tree) is expected
    if expected is not R:
        assert State.RUNNING not in states(kids)


def test_parallel_that_can_no_longer_succeed_fails_instead_of_restarting() -> None:
    a, b, c = leaves(S, F, R)
    tree = Tree(Parallel("par", children=[a, b, c], success_threshold=2, failure_threshold=3))
    assert tick(tree) is R
    c.result = F
    assert tick(tree) is F
    assert ticks([a, b, c]) == [1, 1, 2]  # finished children were not restarted meanwhile


def test_parallel_without_children_succeeds() -> None:
    assert tick(Tree(Parallel("par"))) is S


def test_parallel_halts_running_children_in_the_tick_it_decides() -> None:
    a, b, c = leaves(R, R, R)
    tree = Tree(ReactiveSequence("root", children=[Parallel("par", children=[a, b, c])]))
    assert tick(tree) is R
    b.result = F
    assert tick(tree) is F
    assert states([a, b, c]) == [State.PAUSED, F, State.PAUSED]
    assert [a.unticks, c.unticks] == [1, 1]


def test_parallel_children_running_at_success_are_unticked() -> None:
    a, b = leaves(S, R)
    tree = Tree(Parallel("par", children=[a, b], success_threshold=1))
    assert tick(tree) is S
    assert b.state is State.PAUSED
    assert b.unticks == 1


def test_parallel_reticked_after_finishing_restarts() -> None:
    a, b = leaves(S, S)
    tree = Tree(Parallel("par", children=[a, b]))
    assert tick(tree) is S
    b.result = R
    assert tick(tree) is R
    assert ticks([a, b]) == [2, 2]


def test_parallel_resumes_after_untick() -> None:
    a, b = leaves(S, R)
    tree = Tree(Parallel("par", children=[a, b]))
    tick(tree)
    tree.untick()
    assert b.state is State.PAUSED
    tick(tree)
    assert ticks([a, b]) == [1, 2]
    tree.reset()
    tick(tree)
    assert ticks([a, b]) == [2, 3]


@pytest.mark.parametrize("waiting", [State.UNASSIGNED, State.ASSIGNED, State.PAUSED])
def test_parallel_waiting_children_count_as_running(waiting: State) -> None:
    a, b = leaves(S, waiting)
    tree = Tree(Parallel("par", children=[a, b]))
    assert tick(tree) is R
    b.result = S
    assert tick(tree) is S


def test_parallel_error_counts_as_failure() -> None:
    bad = Leafy("bad", RuntimeError("x"))
    tree = Tree(Parallel("par", children=[bad, Leafy("ok", R)]))
    with capture_logs():
        assert tick(tree) is F


@pytest.mark.parametrize(
    ("success", "failure", "message"),
    [
        (3, None, r"success_threshold 3 can never be met with 2 children \(expected -3\.\.2\)"),
        (-4, None, "success_threshold -4 can never be met"),
        (1, 0, r"failure_threshold 0 can never be met with 2 children \(expected 1\.\.2 or"),
        (1, 3, "failure_threshold 3 can never be met"),
        (1, -3, "failure_threshold -3 can never be met"),
    ],
)
def test_parallel_impossible_thresholds_are_rejected_naming_the_node(
    success: int, failure: int | None, message: str
) -> None:
    par = Parallel(
        "par", children=leaves(S, S), success_threshold=success, failure_threshold=failure
    )
    tree = Tree(ReactiveSequence("root", children=[par]))
    with pytest.raises(TreeError, match=f"node 'root/par' \\(Parallel\\): {message}"):
        tree.validate()
    with pytest.raises(TreeError, match=message):
        tree.setup()
    assert par.state is State.UNINITIALIZED  # nothing was set up, nothing ticked


def test_parallel_impossible_threshold_in_a_file_is_a_load_error() -> None:
    text = """
btcap: 1
name: t
root:
  type: ReactiveSequence
  name: root
  children:
    - type: Parallel
      name: par
      options: {success_threshold: 3}
      children:
        - {type: AlwaysSuccess, name: a}
        - {type: AlwaysSuccess, name: b}
"""
    with pytest.raises(TreeError, match=r"node 'root/par'.*success_threshold 3 can never be met"):
        loads_tree(text)


def test_parallel_children_added_later_are_counted() -> None:
    a, b = leaves(S, R)
    par = Parallel("par", children=[a], success_threshold=-1)
    tree = Tree(par)
    assert tick(tree) is S
    par.add_child(b)
    assert tick(tree) is R  # -1 now means both
    b.result = S
    assert tick(tree) is S


# -- IfThenElse -----------------------------------------------------------------------


def test_if_then_else_takes_the_branch_of_the_condition() -> None:
    cond, then, other = Leafy("cond", S), Leafy("then", R), Leafy("else", R)
    tree = Tree(IfThenElse("ite", children=[cond, then, other]))
    assert tick(tree) is R
    assert ticks([cond, then, other]) == [1, 1, 0]
    then.result = F
    assert tick(tree) is F
    cond.result = F
    other.result = S
    assert tick(tree) is S
    assert ticks([cond, then, other]) == [3, 2, 1]


def test_if_then_else_switching_branch_unticks_the_other() -> None:
    cond, then, other = Leafy("cond", S), Leafy("then", R), Leafy("else", R)
    tree = Tree(IfThenElse("ite", children=[cond, then, other]))
    tick(tree)
    cond.result = F
    assert tick(tree) is R
    assert then.state is State.PAUSED
    assert other.state is R
    cond.result = S
    assert tick(tree) is R
    assert other.state is State.PAUSED
    assert then.state is R


def test_if_then_else_running_condition_pauses_both_branches() -> None:
    cond, then, other = Leafy("cond", S), Leafy("then", R), Leafy("else", R)
    tree = Tree(IfThenElse("ite", children=[cond, then, other]))
    tick(tree)
    cond.result = State.UNASSIGNED
    assert tick(tree) is R
    assert then.state is State.PAUSED
    assert ticks([cond, then, other]) == [2, 1, 0]


def test_if_then_without_else_fails_when_the_condition_fails() -> None:
    cond, then = Leafy("cond", F), Leafy("then", S)
    tree = Tree(IfThenElse("ite", children=[cond, then]))
    assert tick(tree) is F
    assert then.ticks == 0
    cond.result = State.ERROR
    assert tick(tree) is F
    cond.result = S
    assert tick(tree) is S


@pytest.mark.parametrize("waiting", WAITING)
def test_if_then_else_branch_waiting_counts_as_running(waiting: State) -> None:
    tree = Tree(IfThenElse("ite", children=[Leafy("c", S), Leafy("t", waiting)]))
    assert tick(tree) is R


def test_if_then_else_child_count() -> None:
    with pytest.raises(TreeError, match="at most 3 children"):
        IfThenElse("ite", children=leaves(S, S, S, S))
    tree = Tree(IfThenElse("ite", children=leaves(S)))
    with pytest.raises(TreeError, match=r"'ite' \(IfThenElse\) has 1 children; expected 2 to 3"):
        tick(tree)


# -- Switch -----------------------------------------------------------------------------


def test_switch_ticks_the_matching_case() -> None:
    a, b, c = leaves(S, F, R)
    sw = Switch("sw", children=[a, b, c], cases=["a", "b", "c"])
    tree = Tree(sw)
    for value, expected in [("a", S), ("b", F), ("c", R)]:
        sw.set_input("value", value)
        assert tick(tree) is expected
    assert ticks([a, b, c]) == [1, 1, 1]


def test_switch_without_a_match_fails_or_takes_the_default() -> None:
    a, b = leaves(S, S)
    sw = Switch("sw", children=[a, b], cases=[1, 2])
    tree = Tree(sw)
    sw.set_input("value", 3)
    assert tick(tree) is F
    assert ticks([a, b]) == [0, 0]

    a, default = leaves(F, S)
    sw = Switch("sw", children=[a, default], cases=[1])
    tree = Tree(sw)
    sw.set_input("value", 1)
    assert tick(tree) is F
    sw.set_input("value", 99)
    assert tick(tree) is S
    assert ticks([a, default]) == [1, 1]


def test_switch_changing_branch_unticks_the_old_one() -> None:
    a, b = leaves(R, R)
    sw = Switch("sw", children=[a, b], cases=["a"])
    tree = Tree(sw)
    sw.set_input("value", "a")
    tick(tree)
    sw.set_input("value", "other")
    assert tick(tree) is R
    assert a.state is State.PAUSED
    assert b.state is R
    sw.set_input("value", "nothing")  # still the default: b keeps running
    tick(tree)
    assert b.state is R
    assert b.unticks == 0


def test_switch_no_match_unticks_the_old_branch() -> None:
    a, b = leaves(R, R)
    sw = Switch("sw", children=[a, b], cases=["a", "b"])
    tree = Tree(sw)
    sw.set_input("value", "a")
    tick(tree)
    sw.set_input("value", "z")
    assert tick(tree) is F
    assert a.state is State.PAUSED


def test_switch_value_from_a_wire() -> None:
    sw = Switch("sw", children=leaves(F, S), cases=[1, 2])
    tree = Tree(ReactiveSequence("root", children=[Constant("k", value=2, type=int), sw]))
    tree.wire("root/k", "value", "root/sw", "value")
    assert tick(tree) is S


@pytest.mark.parametrize("cases", [[], [1, 2, 3, 4]])
def test_switch_wrong_number_of_cases_fails_setup(cases: list[int]) -> None:
    tree = Tree(Switch("sw", children=leaves(S, S), cases=cases))
    with capture_logs(), pytest.raises(TreeError, match="cases for 2 children; expected 2 or 1"):
        tick(tree)


def test_switch_needs_cases() -> None:
    with pytest.raises(TreeError, match="option 'cases'"):
        Switch("sw", children=leaves(S))


# -- nesting ----------------------------------------------------------------------------


def test_nested_halting_reaches_grandchildren() -> None:
    guard = Leafy("guard", S)
    deep = Leafy("deep", R)
    inner = ReactiveSequence("inner", children=[Leafy("x", S), deep])
    tree = Tree(
        ReactiveFallback(
            "root", children=[Leafy("never", F), ReactiveSequence("s", children=[guard, inner])]
        )
    )
    assert tick(tree) is R
    guard.result = R
    tick(tree)
    assert inner.state is State.PAUSED
    assert deep.state is State.PAUSED
    assert deep.unticks == 1


def test_always_leaves_in_composites() -> None:
    assert tick(Tree(ReactiveSequence("s", children=[AlwaysSuccess(), AlwaysRunning()]))) is R
    assert tick(Tree(ReactiveFallback("f", children=[AlwaysFailure(), AlwaysSuccess()]))) is S
