"""Least privilege for node actions (issue 19.4): no other system reaches a robot's BT
nodes; the origin drives the run it owns through the run's handle only.

The five attacks a member key got through before (a stop tick to the origin's mission
node, Shutdown to a hosted run's leaf, Reset to its root, Shutdown and Reset to the
origin's mission root) come from an attacker system over an in-process network, keyless
tcp and CURVE tcp with a trusted key; each is refused, counted and logged once, and
the mission still ends as the origin decides. Loopback only, free ports.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

import anyio
import pytest
from structlog.testing import capture_logs

from btcap import ReactiveSequence as SequenceNode
from btcap import State, Tree
from btcap.bench.attacks.nodes import ATTACKS, MODES, REPEAT, node_team, strike
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.proxies import RemoteExecution
from btcap.team.demo import ECHO
from btcap.team.messages import RunState

pytestmark = pytest.mark.slow

TICK_S = 0.01


async def tick_until(tree: Tree, cond: Callable[[], bool]) -> None:
    """Tick ``tree`` until ``cond()``; the caller bounds it with fail_after."""
    while True:
        tree.tick()
        if cond():
            return
        await asyncio.sleep(TICK_S)


async def until(cond: Callable[[], bool]) -> None:
    """Wait (the loop runs the team) until ``cond()``; the caller bounds it."""
    while True:
        if cond():
            return
        await asyncio.sleep(TICK_S)


@pytest.mark.parametrize("mode", MODES)
async def test_node_actions_from_another_system_are_refused_counted_and_logged_once(
    mode: str,
) -> None:
    with anyio.fail_after(60):
        async with node_team(mode) as (origin, r1, mallory):
            for attack in ATTACKS:
                with capture_logs() as logs:
                    out = await strike(origin, r1, mallory, attack)
                assert not out.succeeded, out
                assert out.obeyed == 0
                assert out.refused == out.counted == REPEAT, out
                assert out.final == State.SUCCEEDED.name
                assert out.assignments == ["r1"]
                assert out.value == 2  # the value the origin gave last: work finished
                lines = [e for e in logs if e["event"] == "actors.refused"]
                kind = type(attack.msg).__name__
                assert [(e["sender"], e["message"], e["to"]) for e in lines] == [
                    ("mallory", kind, out.target)
                ], attack.name
                assert lines[0]["count"] == 1
            # Shutdown and Reset each reached both robots (a hosted run, a mission root).
            assert origin.system.stats.refused == {
                "Tick": REPEAT,
                "Shutdown": REPEAT,
                "Reset": REPEAT,
            }
            assert r1.system.stats.refused == {"Shutdown": REPEAT, "Reset": REPEAT}


@pytest.mark.parametrize("mode", MODES)
async def test_the_origin_still_ticks_pauses_and_cancels_its_remote_run(mode: str) -> None:
    """Through the run's handle: inputs out and status back every tick, a pause that
    keeps the run, a resume, and a cancel that leaves no trace on the executor."""
    with anyio.fail_after(60):
        async with node_team(mode) as (origin, r1, _mallory):
            node = ECHO.node_type()("echo", inputs={"value": 1})
            assert isinstance(node, Capability)
            tree = origin.mission(SequenceNode("root", children=[node]), name="legit")
            await tick_until(tree, lambda: node.state is State.RUNNING)
            ex = node.execution
            assert isinstance(ex, RemoteExecution)
            assert ex.robot == "r1"
            hosted = r1.mission_control.host.hosted[ex.id]
            for value in (5, 8):
                node.set_input("value", value)
                await tick_until(tree, lambda v=value: node.outputs["value"] == v)

            tree.untick()
            assert node.state is State.PAUSED
            await until(lambda: hosted.paused and hosted.state is RunState.PAUSED)
            assert hosted.run.tree.root.state is State.PAUSED
            frozen = node.outputs["ticks"]
            await tick_until(tree, lambda: not hosted.paused and node.outputs["ticks"] > frozen)
            assert r1.mission_control.host.hosted[ex.id] is hosted  # the same run resumed

            tree.reset()  # the origin cancels its run
            assert node.execution is None
            await until(lambda: not r1.mission_control.host.hosted)
            assert r1.mission_control.body.running is None
            assert node.assignments == ["r1"]
            assert origin.system.stats.refused == r1.system.stats.refused == {}
            await tree.shutdown()
