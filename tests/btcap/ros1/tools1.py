"""Helpers of the ROS 1 bridge tests: a bridge on the test's master, ticking a node until
it ends, and what the master still has registered. The test's ``anyio.fail_after`` bounds
every wait."""

from __future__ import annotations

from collections.abc import Callable

import anyio
from rosmaster1 import Master

from btcap.bt.node import Node
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.client1 import Ros1Bridge
from btcap.team.rossettings import RosSettings

__all__ = ["FOUND_S", "bridge_on", "registered", "run", "settle"]

#: ``server_timeout`` of a node whose server is there: a bound for a loaded machine.
FOUND_S = 15.0


def bridge_on(master: Master, robot: str = "husky1") -> Ros1Bridge:
    return Ros1Bridge(RosSettings(backend="ros1", master_uri=master.uri), robot=robot)


async def run(
    node: Node, done: Callable[[State], bool] = lambda s: s is not State.RUNNING
) -> State:
    """Tick ``node`` (in a tree of its own) every 2 ms until ``done``."""
    tree = node._tree
    if tree is None:
        tree = Tree(node)
        tree.setup()
    while True:
        state = tree.tick()
        if done(state):
            return state
        await anyio.sleep(0.002)


async def settle(cond: Callable[[], bool]) -> None:
    while not cond():  # noqa: ASYNC110 (set by other processes, not by this loop)
        await anyio.sleep(0.01)


def registered(master: Master) -> list[str]:
    """Every publisher, subscriber and service registration on the master, as
    ``kind name node`` lines."""
    with master.proxy() as proxy:
        code, _, state = proxy.getSystemState("/btcap_test")
    assert code == 1
    out = []
    for kind, entries in zip(("pub", "sub", "srv"), state, strict=True):
        for name, nodes in entries:
            out += [f"{kind} {name} {n}" for n in nodes]
    return sorted(out)
