"""Nothing holds an agent's event loop: no module is imported on it once robots run (a
lazy import of numpy and scipy by the first batch of auctions held the operator's loop
for 1.7 s, and its team declared it failed), and planning a batch of auctions runs in a
worker thread on a real clock.

Judged by what ran where (the importing thread, the planning thread), never by a clock,
so the machine's load cannot decide them.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import threading
from collections.abc import Sequence, Set
from pathlib import Path

import anyio
import pytest
from capfixtures import COUNT, Probe, count_impl, team

from btcap import Parallel, State
from btcap.team.allocation.strategies import BatchStrategy
from btcap.team.core.planning import PLANNING_MODULES, optimal_plan
from btcap.team.core.turns import Planned
from btcap.team.messages import Bid

ROOT = Path(__file__).resolve().parents[4]

#: A fresh interpreter runs the examples' mission (three Greet tasks at once: a batch of
#: three auctions, planned) on a team of three robots and an operator, over ZeroMQ tcp
#: loopback at real time (as ``examples/team`` runs it, in one process), and prints the
#: modules imported in a thread running an event loop once the robots had started (an
#: import there holds the loop: numpy and scipy take a second).
FIRST_BATCH = """
import asyncio, json, sys
from pathlib import Path

on_loop = []
watching = False

class Watch:
    def find_spec(self, name, path=None, target=None):
        if not watching:
            return None
        try:
            asyncio.get_running_loop()
        except RuntimeError:
            return None  # not a loop's thread
        if name not in sys.modules:
            on_loop.append(name)
        return None

from btcap.bt.files import load_tree
from btcap.bt.registry import default_registry
from btcap.team.capabilities.capfiles import load_implementation, load_interfaces
from btcap.team.capabilities.capfiles import register_interfaces
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.background import start_in_background
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports.zeromq import ZmqTransport

examples = Path(sys.argv[1])
registry = default_registry(plugins=False)
interfaces = load_interfaces(examples / "capabilities" / "interfaces.yaml", registry)
register_interfaces(registry, interfaces)
greet = load_implementation(examples / "capabilities" / "greet.yaml", interfaces, registry)
mission = load_tree(examples / "team" / "mission.yaml", registry)
config = AgentConfig(heartbeat_s=0.1, failure_timeout_s=5.0, lease_s=5.0, auction_window_s=30.0)


async def main():
    global watching
    robots, known = [], {}
    for name in ("alpha", "beta", "gamma", "operator"):
        wire = protocol_registry()
        transport = ZmqTransport(name, "tcp://127.0.0.1:*", wire, peers=dict(known))
        agent = Agent(name, transport=transport, registry=wire, config=config,
                      implementations=[] if name == "operator" else [greet])
        robots.append(await start_in_background(agent))
        known[name] = transport.endpoint
    operator = robots[-1].agent
    while len(operator.repository.providers(greet.interface.identity)) < 3:
        await asyncio.sleep(0.01)
    watching = True
    state = await asyncio.wait_for(operator.run_mission(mission), 60)
    watching = False
    for life in reversed(robots):
        await life.stop()
    return state.value

sys.meta_path.insert(0, Watch())
state = asyncio.run(main())
print(json.dumps({"state": state, "on_loop": on_loop}))
"""


def test_the_first_batch_of_auctions_of_a_fresh_process_imports_nothing_on_the_loop() -> None:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(FIRST_BATCH), str(ROOT / "examples")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    said = json.loads(done.stdout.splitlines()[-1])
    assert said["state"] == "succeeded", done.stdout
    assert said["on_loop"] == [], "imported on the event loop (a stall of the loop)"


@pytest.mark.asyncio
async def test_a_batch_is_planned_in_a_worker_thread_and_one_auction_on_the_loop() -> None:
    """On a real clock: the plan of a batch of several auctions runs in a worker thread,
    the plan of a lone auction on the loop (the fast path)."""
    loop_thread = threading.get_ident()
    planned: list[tuple[int, bool]] = []  # (auctions in the batch, on the loop's thread)

    def plan(bids: Sequence[Sequence[Bid]], taken: Set[str]) -> list[str | None]:
        planned.append((len(bids), threading.get_ident() == loop_thread))
        return optimal_plan(bids, taken)

    strategy = BatchStrategy("watched", Planned(plan, extended=True, modules=PLANNING_MODULES))
    probe = Probe()
    with anyio.fail_after(60):
        async with team(real_time=True, strategy=strategy) as t:
            origin = await t.add("a")
            for robot in ("b", "c", "d"):
                await t.add(robot, [count_impl(robot, 1.0, probe, after=2)])
            await t.converged()
            lone = await origin.run_mission(COUNT.node_type()("one", inputs={"x": 1}))
            nodes = [COUNT.node_type()(f"n{i}", inputs={"x": i}) for i in range(3)]
            three = await origin.run_mission(Parallel("all", children=nodes))
    assert (lone, three) == (State.SUCCEEDED, State.SUCCEEDED)
    assert planned[0] == (1, True)
    assert any(n > 1 for n, _ in planned), planned  # the three auctions ran together
    assert all(on_loop == (n == 1) for n, on_loop in planned), planned


#: A fresh interpreter starts a robot, then an agent that will hold missions, each with
#: the default (optimal) strategy and no mission attached; prints which planning modules
#: were loaded after each, and on which threads they were imported.
AHEAD = """
import asyncio, json, sys, threading

imported = {}

class Watch:
    def find_spec(self, name, path=None, target=None):
        if name in ("numpy", "scipy.optimize") and name not in imported:
            imported[name] = threading.current_thread() is threading.main_thread()
        return None

sys.meta_path.insert(0, Watch())
from btcap.team.runtime.agent import Agent
from btcap.team.core.planning import PLANNING_MODULES

async def main():
    async with Agent("robot") as robot:
        assert robot.strategy.name == "optimal"
        await asyncio.sleep(0)
    robot_loaded = [m for m in PLANNING_MODULES if m in sys.modules]
    async with Agent("operator", missions=True):
        for _ in range(6000):  # the worker thread's import, bounded by the test's timeout
            if all(m in sys.modules for m in PLANNING_MODULES):
                break
            await asyncio.sleep(0.01)
    return robot_loaded

robot_loaded = asyncio.run(main())
print(json.dumps({"robot": robot_loaded, "on_main_thread": imported}))
"""


def test_an_agent_that_will_hold_missions_imports_its_planners_as_it_starts_off_the_loop() -> None:
    """The first batch of auctions of an operator does not wait for numpy and scipy: they
    are imported in a worker thread as it starts (before joining), with no mission
    attached yet; a robot that only runs others' work never imports them."""
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(AHEAD)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    said = json.loads(done.stdout.splitlines()[-1])
    assert said["robot"] == []
    assert said["on_main_thread"] == {"numpy": False, "scipy.optimize": False}
