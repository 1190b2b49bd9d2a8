"""News from outside a tree (a ROS goal answered, handed to the loop) ticks it soon:
``Tree.nudge`` cuts the sleep of ``Tree.run`` short for one extra tick, and the periodic
ticks keep their times; a tree ticked by another passes the nudge on."""

from __future__ import annotations

import asyncio

import anyio

from btcap.actors import ManualClock
from btcap.bt.leaves import Leaf
from btcap.bt.state import State
from btcap.bt.tree import Subtree, Tree


class Flag(Leaf):
    """RUNNING until ``done``; counts its ticks."""

    def __init__(self, name: str = "flag") -> None:
        self.done = False
        self.ticks = 0
        super().__init__(name)

    def on_tick(self) -> State:
        self.ticks += 1
        return State.SUCCEEDED if self.done else State.RUNNING


async def _settle() -> None:
    for _ in range(20):
        await asyncio.sleep(0)


async def test_a_nudge_ticks_at_once_without_the_clock_moving() -> None:
    clock = ManualClock()
    leaf = Flag()
    tree = Tree(leaf, clock=clock)
    with anyio.fail_after(5):
        run = asyncio.ensure_future(tree.run(rate_hz=1.0))
        await _settle()
        assert leaf.ticks == 1  # the first tick; the next is a clock second away
        tree.nudge()
        tree.nudge()  # coalesced: one tick for both
        await _settle()
        assert leaf.ticks == 2
        leaf.done = True
        asyncio.get_running_loop().call_soon(tree.nudge)  # as a Waker hands it over
        assert await run is State.SUCCEEDED
    assert clock.now() == 0.0
    assert leaf.ticks == 3


async def test_nudged_ticks_are_extra_the_period_keeps_its_times() -> None:
    clock = ManualClock()
    leaf = Flag()
    tree = Tree(leaf, clock=clock)
    with anyio.fail_after(5):
        run = asyncio.ensure_future(tree.run(rate_hz=1.0))
        await _settle()
        await clock.advance(0.5)
        tree.nudge()
        await _settle()
        assert leaf.ticks == 2
        await clock.advance(0.5)  # the periodic tick of t=1, not one of t=1.5
        assert leaf.ticks == 3
        await clock.advance(0.9)
        assert leaf.ticks == 3
        leaf.done = True
        await clock.advance(0.1)
        assert await run is State.SUCCEEDED
    assert leaf.ticks == 4


async def test_a_nudge_inside_a_subtree_ticks_the_outer_tree() -> None:
    clock = ManualClock()
    leaf = Flag()
    outer = Tree(Subtree(Tree(leaf), "sub"), clock=clock)
    with anyio.fail_after(5):
        run = asyncio.ensure_future(outer.run(rate_hz=1.0))
        await _settle()
        assert leaf._tree is not None
        leaf.done = True
        leaf._tree.nudge()  # the inner tree is not run by itself: its ticker is
        assert await run is State.SUCCEEDED
    assert clock.now() == 0.0
