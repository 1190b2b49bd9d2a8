"""AsyncSequence, AsyncSequenceWithMemory, AsyncFallback and WhileDoElse on their own
(BehaviorTree.CPP itself checks them in test_btcpp_oracle.py where its wheel exists)."""

from __future__ import annotations

import anyio
import pytest

from btcap import (
    AsyncFallback,
    AsyncSequence,
    AsyncSequenceWithMemory,
    IfThenElse,
    LatchedIfThenElse,
    Leaf,
    ParallelAll,
    ReactiveSequence,
    Retry,
    Sequence,
    State,
    Subtree,
    Tree,
    TreeError,
    WhileDoElse,
)
from btcap.actors import ManualClock
from btcap.bt.invariants import tick_checked as tick
from btcap.bt.node import Node

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


class Scripted(Leaf):
    """Gives ``script[k]`` on its k-th tick (the last one after that); counts ticks."""

    __slots__ = ("script", "ticks")

    def __init__(self, name: str, *script: State) -> None:
        super().__init__(name)
        self.script = script
        self.ticks = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return self.script[min(self.ticks, len(self.script)) - 1]


def test_async_sequence_yields_so_a_reactive_parent_can_preempt() -> None:
    c, l0, l1 = Scripted("c", S, F), Scripted("l0", S), Scripted("l1", S)
    tree = Tree(ReactiveSequence("rs", children=[c, AsyncSequence("a", children=[l0, l1])]))
    assert tick(tree) is R
    assert tick(tree) is F
    assert (l0.ticks, l1.ticks) == (1, 0)


def test_plain_sequence_runs_instant_children_in_one_tick() -> None:
    """The difference the yield makes (what AsyncSequence was mapped to before)."""
    c, l0, l1 = Scripted("c", S, F), Scripted("l0", S), Scripted("l1", S)
    tree = Tree(ReactiveSequence("rs", children=[c, Sequence("a", children=[l0, l1])]))
    assert tick(tree) is S


def test_no_yield_after_a_child_that_was_running_or_after_the_last() -> None:
    a, b, c = Scripted("a", R, S), Scripted("b", S), Scripted("c", S)
    tree = Tree(AsyncSequence("s", children=[a, b, c]))
    assert tick(tree) is R  # a runs
    assert tick(tree) is R  # a succeeds after running: b ticked too, succeeds at once
    assert (a.ticks, b.ticks, c.ticks) == (2, 1, 0)
    assert tick(tree) is S  # c is the last: nothing to yield for
    assert c.ticks == 1


def test_async_sequence_with_memory_resumes_at_the_failed_child() -> None:
    a, b = Scripted("a", S), Scripted("b", F, S)
    tree = Tree(AsyncSequenceWithMemory("s", children=[a, b]))
    assert [tick(tree), tick(tree), tick(tree)] == [R, F, S]
    assert (a.ticks, b.ticks) == (1, 2)


def test_async_fallback_yields_after_an_instant_failure() -> None:
    a, b = Scripted("a", F), Scripted("b", S)
    tree = Tree(AsyncFallback("f", children=[a, b]))
    assert [tick(tree), tick(tree)] == [R, S]
    assert (a.ticks, b.ticks) == (1, 1)


def _branches(kind: type[Node]) -> tuple[Tree, Scripted]:
    cond, then = Scripted("cond", S, R, R, S), Scripted("then", R, R, S)
    return Tree(kind("w", children=[cond, then, Scripted("else", R)])), then


def test_while_do_else_keeps_the_branch_running_while_the_condition_runs() -> None:
    tree, then = _branches(WhileDoElse)
    assert [tick(tree) for _ in range(3)] == [R, R, R]  # the invariant check allows the hold
    assert then.state is State.RUNNING
    assert then.ticks == 1
    assert tick(tree) is R
    assert then.ticks == 2


def test_if_then_else_unticks_the_branch_while_the_condition_runs() -> None:
    tree, then = _branches(IfThenElse)
    assert [tick(tree) for _ in range(3)] == [R, R, R]
    assert then.state is State.PAUSED


def test_while_do_else_without_else_fails_and_halts_the_branch() -> None:
    cond, then = Scripted("cond", S, F), Scripted("then", R)
    tree = Tree(WhileDoElse("w", children=[cond, then]))
    assert [tick(tree), tick(tree)] == [R, F]
    assert then.state is State.PAUSED


def test_latched_if_then_else_checks_the_condition_only_until_a_branch_runs() -> None:
    cond, then = Scripted("cond", S, F), Scripted("then", R, R, S)
    tree = Tree(LatchedIfThenElse("i", children=[cond, then, Scripted("else", S)]))
    assert [tick(tree), tick(tree), tick(tree)] == [R, R, S]
    assert (cond.ticks, then.ticks) == (1, 3)
    assert tick(tree) is S  # the condition decides again: it fails, the else branch runs
    assert cond.ticks == 2


def test_latched_if_then_else_without_else_fails_with_its_condition() -> None:
    tree = Tree(LatchedIfThenElse("i", children=[Scripted("cond", F), Scripted("then", S)]))
    assert tick(tree) is F


def test_parallel_all_waits_for_every_child_then_counts_failures() -> None:
    a, b, c = Scripted("a", F), Scripted("b", R, S), Scripted("c", R, R, F)
    tree = Tree(ParallelAll("p", children=[a, b, c], max_failures=2))
    assert [tick(tree), tick(tree), tick(tree)] == [R, R, F]
    assert (a.ticks, b.ticks, c.ticks) == (1, 2, 3)  # a finished child is not ticked again
    one = Tree(ParallelAll("p", children=[Scripted("a", F), Scripted("b", S)], max_failures=-1))
    assert tick(one) is S  # -1: all of them must fail


def test_parallel_all_refuses_a_threshold_it_can_never_meet() -> None:
    tree = Tree(ParallelAll("p", children=[Scripted("a", S)], max_failures=2))
    with pytest.raises(TreeError, match=r"max_failures 2 can never be met with 1 children"):
        tree.setup()


# -- the two tick modes (BehaviorTree.CPP's tickOnce and tickExactlyOnce) ---------------


def test_tick_once_ticks_again_at_once_when_a_node_yields() -> None:
    """An AsyncSequence of three instant children: 1 tickOnce, 3 tickExactlyOnce."""
    leaves = [Scripted(f"l{i}", S) for i in range(3)]
    once = Tree(AsyncSequence("a", children=leaves))
    assert once.tick_once() is S
    assert [leaf.ticks for leaf in leaves] == [1, 1, 1]
    exactly = Tree(AsyncSequence("a", children=[Scripted(f"m{i}", S) for i in range(3)]))
    assert [exactly.tick(), exactly.tick(), exactly.tick()] == [R, R, S]
    assert Tree.tick_exactly_once is Tree.tick


def test_a_retry_of_an_instant_child_asks_to_be_ticked_again_not_of_a_running_one() -> None:
    instant = Tree(Retry("r", children=[Scripted("a", F, S)], retries=1))
    assert instant.tick_once() is S
    running = Tree(Retry("r", children=[Scripted("b", R, F, S)], retries=1))
    assert [running.tick_once(), running.tick_once()] == [R, R]  # the retry waits a tick
    assert running.tick_once() is S


def test_a_subtree_passes_its_nodes_request_to_the_outer_tree() -> None:
    inner = Tree(AsyncSequence("a", children=[Scripted("x", S), Scripted("y", S)]))
    outer = Tree(Sequence("s", children=[Subtree(inner, "sub")]))
    assert outer.tick_once() is S


async def test_run_with_wake_ticks_again_without_waiting_for_the_period() -> None:
    with anyio.fail_after(5):
        for wake, elapsed in ((True, 0.0), (False, 0.2)):
            clock = ManualClock()
            leaves = [Scripted(f"l{i}", S) for i in range(3)]
            tree = Tree(AsyncSequence("a", children=leaves), clock=clock)
            async with clock.autojump():
                assert await tree.run(10.0, wake=wake) is S
            assert clock.now() == pytest.approx(elapsed)
