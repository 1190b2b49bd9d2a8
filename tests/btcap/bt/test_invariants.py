"""The halting invariant check: it catches abandoned running nodes and allows held ones."""

from __future__ import annotations

import pytest
from structlog.testing import capture_logs

from btcap import Leaf, Node, ReactiveSequence, State, Subtree, Throttle, Tree
from btcap.actors import ManualClock
from btcap.bt.composites import Composite
from btcap.bt.decorators import Decorator
from btcap.bt.invariants import HaltingViolation, record_ticks, tick_checked

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


class Fixed(Leaf):
    def __init__(self, name: str, result: State) -> None:
        super().__init__(name)
        self.result = result

    def on_tick(self) -> State:
        return self.result


class FirstOnlyOnce(Composite):
    """Broken on purpose: ticks its first child once, then only the second, never halting."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.first_done = False

    def on_tick(self) -> State:
        if not self.first_done:
            self.first_done = True
            self.children[0].tick()
        return self.children[1].tick()


class SwallowRunning(Decorator):
    """Broken on purpose: reports success for a running child and leaves it running."""

    def on_tick(self) -> State:
        self.children[0].tick()
        return S


def test_a_running_node_nobody_ticks_is_reported() -> None:
    tree = Tree(FirstOnlyOnce("root", children=[Fixed("a", R), Fixed("b", R)]))
    assert tick_checked(tree) is R
    with pytest.raises(HaltingViolation, match="root/a is running but was not ticked"):
        tick_checked(tree)


def test_a_running_node_under_a_finished_parent_is_reported_the_same_tick() -> None:
    tree = Tree(
        ReactiveSequence("root", children=[SwallowRunning("dec", children=[Fixed("a", R)])])
    )
    with pytest.raises(HaltingViolation, match=r"root/dec/a is running below root/dec, which is"):
        tick_checked(tree)


def test_record_ticks_lists_the_nodes_ticked_in_order() -> None:
    a, b, c = Fixed("a", S), Fixed("b", F), Fixed("c", S)
    tree = Tree(ReactiveSequence("root", children=[a, b, c]))
    state, ticked = record_ticks(tree, tree.tick)
    assert state is F
    assert [n.name for n in ticked] == ["root", "a", "b"]


async def test_a_throttle_may_hold_its_running_child_between_its_ticks() -> None:
    clock = ManualClock()
    deep = Fixed("deep", R)
    tree = Tree(
        Throttle("thr", children=[ReactiveSequence("s", children=[deep])], rate_hz=1), clock=clock
    )
    assert tick_checked(tree) is R
    assert tick_checked(tree) is R  # child and grandchild running, not ticked: held
    await clock.advance(1.0)
    assert tick_checked(tree) is R


def test_nodes_inside_a_subtree_are_checked() -> None:
    inner = Tree(FirstOnlyOnce("inner", children=[Fixed("a", R), Fixed("b", R)]))
    tree = Tree(ReactiveSequence("root", children=[Subtree(inner, "sub")]))
    tick_checked(tree)
    with pytest.raises(HaltingViolation, match="inner/a is running but was not ticked"):
        tick_checked(tree)


def test_a_node_that_raises_halts_its_running_children() -> None:
    class Explodes(Composite):
        def on_tick(self) -> State:
            self.children[0].tick()
            raise RuntimeError("boom")

    a = Fixed("a", R)
    node: Node = Explodes("x", children=[a])
    tree = Tree(ReactiveSequence("root", children=[node]))
    with capture_logs():
        assert tick_checked(tree) is F
    assert node.state is State.ERROR
    assert a.state is State.PAUSED
