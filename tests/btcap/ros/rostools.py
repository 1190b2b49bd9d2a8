"""Helpers of the ROS tests: ticking a tree until a condition, waiting for what ROS
threads set. The test's ``anyio.fail_after`` bounds every wait."""

from __future__ import annotations

from collections.abc import Callable

import anyio

from btcap.bt.node import Node
from btcap.bt.state import State
from btcap.bt.tree import Tree

__all__ = ["FOUND_S", "tick_until", "tree_of", "wait_for"]

#: ``server_timeout`` of a node whose server is there (the default 1 s is too short for
#: DDS discovery on a loaded machine: "no server after 1.0 s" at load 12 on 2 cores).
#: Tests that expect the timeout keep short ones; this stays under their fail_after(10).
FOUND_S = 8.0


async def tick_until(
    tree: Tree, done: Callable[[State], bool] = lambda s: s is not State.RUNNING
) -> State:
    """Tick every 2 ms until ``done``; the test's fail_after bounds it."""
    while True:
        state = tree.tick()
        if done(state):
            return state
        await anyio.sleep(0.002)


def tree_of(node: Node) -> Tree:
    tree = Tree(node)
    tree.setup()
    return tree


async def wait_for(cond: Callable[[], bool]) -> None:
    while not cond():  # noqa: ASYNC110 (set by ROS threads, not by this loop)
        await anyio.sleep(0.005)
