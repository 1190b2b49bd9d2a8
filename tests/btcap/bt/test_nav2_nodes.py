"""Nav2's control and decorator nodes, one test per rule of Nav2's C++ source.

Nav2 has no Python oracle. The rules were read in ros-navigation/navigation2 at commit
a3a97043 (2026-08-21): nav2_behavior_tree/plugins/control/recovery_node.cpp,
pipeline_sequence.cpp, round_robin_node.cpp and plugins/decorator/rate_controller.cpp,
single_trigger_node.cpp (each test names the file it checks), and the node pages of
docs.nav2.org (configuration/packages/bt-plugins).
"""

from __future__ import annotations

import anyio
import pytest

from actors import ManualClock
from btcap import Leaf, Sequence, State, Tree, TreeError
from btcap.bt.invariants import tick_checked as tick
from btcap.bt.nav2_nodes import (
    PipelineSequence,
    RateController,
    RecoveryNode,
    RoundRobin,
    SingleTrigger,
)

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


class Scripted(Leaf):
    """Gives ``script[k]`` on its k-th tick (the last one after that); counts ticks and
    halts (an untick while running)."""

    __slots__ = ("halts", "script", "ticks")

    def __init__(self, name: str, *script: State) -> None:
        super().__init__(name)
        self.script = script
        self.ticks = 0
        self.halts = 0

    def on_tick(self) -> State:
        self.ticks += 1
        return self.script[min(self.ticks, len(self.script)) - 1]

    def on_untick(self) -> None:
        self.halts += 1


# -- RecoveryNode (plugins/control/recovery_node.cpp) ----------------------------------


def test_recovery_succeeds_without_recovering_when_the_first_child_succeeds() -> None:
    """The bug this replaces: a Sequence stand-in ran the recovery after a success."""
    nav, fix = Scripted("nav", R, S), Scripted("fix", S)
    tree = Tree(RecoveryNode("r", children=[nav, fix]))
    assert [tick(tree), tick(tree)] == [R, S]
    assert fix.ticks == 0


def test_recovery_recovers_then_retries_the_first_child_in_the_same_tick() -> None:
    nav, fix = Scripted("nav", F, S), Scripted("fix", S)
    tree = Tree(RecoveryNode("r", children=[nav, fix]))
    assert tick(tree) is S
    assert (nav.ticks, fix.ticks) == (2, 1)


def test_recovery_fails_once_number_of_retries_recoveries_were_spent() -> None:
    nav, fix = Scripted("nav", F), Scripted("fix", S)
    tree = Tree(RecoveryNode("r", children=[nav, fix], inputs={"number_of_retries": 3}))
    assert tick(tree) is F
    assert (nav.ticks, fix.ticks) == (4, 3)
    assert tick(tree) is F  # counts start over after the result
    assert (nav.ticks, fix.ticks) == (8, 6)


def test_recovery_fails_when_the_recovery_fails() -> None:
    nav, fix = Scripted("nav", F), Scripted("fix", R, F)
    tree = Tree(RecoveryNode("r", children=[nav, fix]))
    assert [tick(tree), tick(tree)] == [R, F]
    assert nav.ticks == 1


def test_recovery_needs_exactly_two_children() -> None:
    with pytest.raises(TreeError, match="expected 2 to 2"):
        Tree(RecoveryNode("r", children=[Scripted("a", S)])).setup()


def test_recovery_halted_starts_again_at_the_first_child_with_no_retries_spent() -> None:
    nav, fix = Scripted("nav", F, F, S), Scripted("fix", R)
    node = RecoveryNode("r", children=[nav, fix])
    tree = Tree(node)
    assert tick(tree) is R  # nav failed, fix runs
    tree.untick()
    assert fix.halts == 1
    assert tick(tree) is R  # nav again (fails), then fix again: one retry still left
    assert (nav.ticks, fix.ticks) == (2, 2)


# -- PipelineSequence (plugins/control/pipeline_sequence.cpp) --------------------------


def test_pipeline_reticks_earlier_children_while_a_later_one_runs() -> None:
    plan, follow = Scripted("plan", S), Scripted("follow", R, R, S)
    tree = Tree(PipelineSequence("p", children=[plan, follow]))
    assert [tick(tree), tick(tree), tick(tree)] == [R, R, S]
    assert (plan.ticks, follow.ticks) == (3, 3)


def test_pipeline_keeps_an_earlier_running_child_running_and_goes_on() -> None:
    plan, follow = Scripted("plan", S, R, R), Scripted("follow", R)
    tree = Tree(PipelineSequence("p", children=[plan, follow]))
    tick(tree)  # plan succeeds, follow starts: the furthest child reached is follow
    assert tick(tree) is R  # plan runs again: not before the furthest, so follow is ticked
    assert follow.ticks == 2


def test_pipeline_fails_at_the_first_failure_and_halts_the_others() -> None:
    plan, follow = Scripted("plan", S, F), Scripted("follow", R)
    tree = Tree(PipelineSequence("p", children=[plan, follow]))
    tick(tree)
    assert tick(tree) is F
    assert follow.halts == 1
    assert follow.state is State.IDLE


# -- RoundRobin (plugins/control/round_robin_node.cpp) ---------------------------------


def test_round_robin_starts_after_the_child_that_succeeded_last() -> None:
    a, b = Scripted("a", S), Scripted("b", S)
    tree = Tree(RoundRobin("rr", children=[a, b], inputs={"wrap_around": True}))
    assert [tick(tree), tick(tree), tick(tree)] == [S, S, S]
    assert (a.ticks, b.ticks) == (2, 1)


def test_round_robin_moves_on_after_a_failure_and_fails_when_all_failed() -> None:
    a, b, c = Scripted("a", F), Scripted("b", F), Scripted("c", F)
    tree = Tree(RoundRobin("rr", children=[a, b, c], inputs={"wrap_around": True}))
    assert tick(tree) is F
    assert (a.ticks, b.ticks, c.ticks) == (1, 1, 1)


def test_round_robin_without_wrap_around_fails_at_the_last_child() -> None:
    """Nav2's rule since #5308: reaching the end ends the run, even on a success."""
    a, b = Scripted("a", F), Scripted("b", S)
    tree = Tree(RoundRobin("rr", children=[a, b]))
    assert tick(tree) is F
    assert (a.ticks, b.ticks) == (1, 1)
    assert tick(tree) is F  # starts over at the first child
    assert a.ticks == 2


# -- RateController (plugins/decorator/rate_controller.cpp) ----------------------------


async def test_rate_controller_ticks_its_child_once_a_period() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        plan, follow = Scripted("plan", S), Scripted("follow", R)
        rate = RateController("rc", children=[plan], inputs={"hz": 1.0})
        tree = Tree(PipelineSequence("p", children=[rate, follow]), clock=clock)
        assert tick(tree) is R
        await clock.advance(0.5)
        assert tick(tree) is R
        assert plan.ticks == 1  # the period has not passed: RUNNING, child not ticked
        await clock.advance(0.5)
        tick(tree)
        assert plan.ticks == 2


def test_rate_controller_ticks_a_running_child_every_tick() -> None:
    clock = ManualClock()
    plan = Scripted("plan", R, R, S)
    tree = Tree(RateController("rc", children=[plan], inputs={"hz": 1.0}), clock=clock)
    assert [tick(tree), tick(tree), tick(tree)] == [R, R, S]


def test_rate_controller_halted_ticks_its_child_at_once_when_ticked_again() -> None:
    clock = ManualClock()
    plan, follow = Scripted("plan", S), Scripted("follow", R)
    tree = Tree(
        PipelineSequence(
            "p", children=[RateController("rc", children=[plan], inputs={"hz": 1.0}), follow]
        ),
        clock=clock,
    )
    tick(tree)
    tree.untick()
    tick(tree)
    assert plan.ticks == 2


# -- SingleTrigger (plugins/decorator/single_trigger_node.cpp) -------------------------


def test_single_trigger_passes_one_result_then_fails_until_halted() -> None:
    child = Scripted("c", R, S)
    node = SingleTrigger("st", children=[child])
    tree = Tree(Sequence("seq", children=[node]))
    assert [tick(tree), tick(tree), tick(tree)] == [R, S, F]
    assert child.ticks == 2
    tree.reset()
    assert tick(tree) is S
    assert child.ticks == 3


# -- a skipped child (the SKIPPED cases of each file above) ----------------------------

K = State.SKIPPED


def test_recovery_is_skipped_when_its_first_child_is() -> None:
    """recovery_node.cpp: first child SKIPPED -> halt(), SKIPPED."""
    nav, fix = Scripted("nav", K), Scripted("fix", S)
    tree = Tree(RecoveryNode("r", children=[nav, fix]))
    assert tick(tree) is K
    assert fix.ticks == 0


def test_recovery_fails_when_its_recovery_is_skipped_keeping_its_retries() -> None:
    """recovery_node.cpp: recovery SKIPPED -> index 0, FAILURE, not a retry spent (and
    retry_count_ kept: no halt())."""
    nav, fix = Scripted("nav", F, F, F, F), Scripted("fix", S, K, S)
    tree = Tree(RecoveryNode("r", children=[nav, fix], inputs={"number_of_retries": 2}))
    assert tick(tree) is F  # nav F, fix S (1 retry spent), nav F, fix K: failure
    assert (nav.ticks, fix.ticks) == (2, 2)
    assert tick(tree) is F  # nav F, fix S (2 retries spent), nav F: retries spent
    assert (nav.ticks, fix.ticks) == (4, 3)


def test_pipeline_passes_a_skipped_child_over_and_is_skipped_when_all_are() -> None:
    """pipeline_sequence.cpp: SKIPPED counted, loop goes on; all skipped -> SKIPPED."""
    a, b, c = Scripted("a", K, K), Scripted("b", R, K), Scripted("c", S)
    tree = Tree(PipelineSequence("p", children=[a, b]))
    assert tick(tree) is R  # a skipped, b runs
    assert tick(tree) is K  # both skipped
    tree2 = Tree(PipelineSequence("p2", children=[Scripted("k", K), c]))
    assert tick(tree2) is S


def test_round_robin_passes_a_skipped_child_over_and_is_skipped_when_all_are() -> None:
    """round_robin_node.cpp: SKIPPED moves to the next child; all skipped -> SKIPPED,
    some failed -> FAILURE."""
    a, b = Scripted("a", K, K), Scripted("b", S, F)
    tree = Tree(RoundRobin("rr", children=[a, b], inputs={"wrap_around": True}))
    assert tick(tree) is S  # a skipped, b succeeds
    assert tick(tree) is F  # starts after b: a skipped, b fails: not all skipped
    both = Tree(RoundRobin("rr2", children=[Scripted("x", K), Scripted("y", K)]))
    assert tick(both) is K


def test_rate_controller_and_single_trigger_pass_skipped_on() -> None:
    """rate_controller.cpp, single_trigger_node.cpp: a skipped child gives SKIPPED and
    SingleTrigger keeps its first time."""
    child = Scripted("c", K, S)
    trigger = Tree(SingleTrigger("t", children=[child]))
    assert [tick(trigger), tick(trigger), tick(trigger)] == [K, S, F]
    rate = Tree(RateController("rc", children=[Scripted("d", K)], inputs={"hz": 1.0}))
    assert tick(rate) is K
