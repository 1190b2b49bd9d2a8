"""Robots in separate OS processes over ZeroMQ tcp loopback.

The origin (the robot whose tree holds the capability node) runs in the test's event loop;
the executors are child processes started with :mod:`btcap.team.deployment.launch` running the demo
``Echo`` capability, each bidding a fixed cost. Every child is killed at teardown.
"""

from __future__ import annotations

import asyncio
import os
import tempfile
from collections.abc import AsyncIterator, Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import anyio
import msgspec
import pytest
import zmq

from btcap import ReactiveSequence as SequenceNode
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.team.capabilities.capability import Capability
from btcap.team.capabilities.proxies import RemoteExecution
from btcap.team.demo import ECHO
from btcap.team.deployment.launch import AgentProcess, AgentSpec, main, spawn_agents
from btcap.team.deployment.spawn import AsyncAgentProcess, open_agent, open_agents
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport

pytestmark = pytest.mark.slow

LOCAL = "tcp://127.0.0.1:*"
TICK_S = 0.01  # the origin ticks its mission trees at 100 Hz while waiting


def spec(robot: str, cost: float, **kw: Any) -> AgentSpec:
    return AgentSpec(
        robot=robot, factory="btcap.team.demo:implementations", factory_args={"cost": cost}, **kw
    )


@pytest.fixture
def logs(tmp_path: Path) -> Path:
    return tmp_path / "children.log"


@pytest.fixture
async def spawn(logs: Path) -> AsyncIterator[Callable[..., Any]]:
    """Start child robots in parallel without blocking the loop (the origin keeps beating).

    Children log to ``logs``; every one is killed at teardown, whatever happened.
    """
    started: list[AsyncAgentProcess] = []
    log_file = logs.open("ab")

    async def start(*groups: AgentSpec | Sequence[AgentSpec]) -> list[AsyncAgentProcess]:
        procs = await open_agents(list(groups), timeout=30.0, stderr=log_file.fileno())
        started.extend(procs)
        return procs

    try:
        yield start
    finally:
        for p in started:
            await p.kill()
        log_file.close()


def origin_agent(peers: dict[str, str], config: AgentConfig | None = None) -> Agent:
    reg = protocol_registry()
    transport = ZmqTransport("origin", LOCAL, reg, peers=peers)
    return Agent("origin", transport=transport, registry=reg, config=config)


def peers_of(procs: Sequence[AsyncAgentProcess]) -> dict[str, str]:
    return {robot: ep for p in procs for robot, ep in p.endpoints.items()}


async def until(tree: Tree | None, cond: Callable[[], bool]) -> None:
    """Tick ``tree`` (if given) until ``cond()``; the caller bounds it with fail_after."""
    while True:
        if tree is not None:
            tree.tick()
        if cond():
            return
        await asyncio.sleep(TICK_S)


async def joined(agent: Agent, robots: set[str]) -> None:
    await until(None, lambda: robots <= agent.repository.providers(ECHO.identity))


def echo_mission(agent: Agent, name: str = "echo") -> tuple[Tree, Capability]:
    node = ECHO.node_type()(name, inputs={"value": 0})
    return agent.mission(SequenceNode(f"root_{name}", children=[node])), node


def running_on(node: Capability, robot: str) -> Callable[[], bool]:
    def check() -> bool:
        ex = node.execution
        return ex is not None and ex.robot == robot and node.state is State.RUNNING

    return check


def acked(ex: RemoteExecution, seq: int) -> Callable[[], bool]:
    return lambda: ex.tracked.acked >= seq


def output_is(node: Capability, value: int) -> Callable[[], bool]:
    return lambda: bool(node.outputs["value"] == value)


async def echo_follows(tree: Tree, node: Capability, values: Sequence[int], robot: str) -> None:
    """Change the input, see the output follow, from ``robot``; every tick is confirmed."""
    ex = node.execution
    assert isinstance(ex, RemoteExecution)
    for value in values:
        node.set_input("value", value)
        tree.tick()
        sent = ex.tracked.seq
        await until(None, acked(ex, sent))  # inputs out, status back
        await until(tree, output_is(node, value))
        assert node.outputs["robot"] == robot


async def finish(tree: Tree, node: Capability) -> None:
    node.set_input("stop", True)
    await until(tree, lambda: tree.root.state is State.SUCCEEDED)
    assert node.state is State.SUCCEEDED


async def test_assigns_to_cheapest_child_and_io_flows_both_ways(spawn: Any) -> None:
    with anyio.fail_after(30):
        procs = await spawn(spec("r1", 1.0), spec("r2", 2.0))
        async with origin_agent(peers_of(procs)) as origin:
            await joined(origin, {"r1", "r2"})
            tree, node = echo_mission(origin)
            await until(tree, running_on(node, "r1"))
            await echo_follows(tree, node, [7, -3, 42, 42, 1000], "r1")
            ticks = node.outputs["ticks"]
            await echo_follows(tree, node, [5], "r1")
            assert node.outputs["ticks"] >= ticks  # the same run goes on on r1
            await finish(tree, node)
            assert node.assignments == ["r1"]
            assert origin.mission_control.stats.lost == 0
            assert origin.allocator.stats.early_closes >= 1
            await tree.shutdown()


async def test_killed_executor_is_replaced_and_tree_succeeds(spawn: Any) -> None:
    with anyio.fail_after(30):
        procs = await spawn(spec("r1", 1.0), spec("r2", 2.0), spec("r3", 3.0))
        by_robot = {p.robot: p for p in procs}
        async with origin_agent(peers_of(procs)) as origin:
            await joined(origin, {"r1", "r2", "r3"})
            tree, node = echo_mission(origin)
            await until(tree, running_on(node, "r1"))
            await echo_follows(tree, node, [1, 2], "r1")
            node.set_input("value", 99)
            tree.tick()

            stats = origin.mission_control.stats
            empty = stats.unassigned
            await by_robot["r1"].kill()  # mid-task, without a word
            await until(tree, running_on(node, "r2"))
            # Re-assigned with its latest inputs at the loss, by events: no auction of it
            # came back empty (which would have waited for its retry_s), one loss.
            assert stats.unassigned == empty
            assert stats.lost == 1
            await until(tree, lambda: node.outputs["robot"] == "r2")
            assert node.outputs["value"] == 99
            await echo_follows(tree, node, [3, 4], "r2")
            await finish(tree, node)
            assert node.assignments == ["r1", "r2"]
            assert origin.mission_control.stats.lost == 1
            assert by_robot["r2"].alive()
            assert by_robot["r3"].alive()
            await tree.shutdown()


async def test_late_joiner_wins_next_auction_without_cancelling_healthy_work(
    spawn: Any,
) -> None:
    with anyio.fail_after(30):
        procs = await spawn(spec("r2", 2.0), spec("r3", 3.0))
        # With re-evaluation off, a join never moves running work.
        async with origin_agent(peers_of(procs), AgentConfig(reevaluate_s=None)) as origin:
            await joined(origin, {"r2", "r3"})
            tree_a, node_a = echo_mission(origin, "a")
            await until(tree_a, running_on(node_a, "r2"))
            execution_a = node_a.execution

            # r1 joins the team knowing only the origin's endpoint; it is the cheapest.
            endpoint = origin.system.transport.endpoint  # type: ignore[union-attr]
            await spawn(spec("r1", 1.0, peers={"origin": endpoint}))
            await joined(origin, {"r1"})
            for _ in range(20):  # the team settles; the healthy run must carry on
                tree_a.tick()
                await asyncio.sleep(TICK_S)
            assert node_a.execution is execution_a

            tree_b, node_b = echo_mission(origin, "b")
            await until(tree_b, running_on(node_b, "r1"))
            assert origin.allocator.outcomes
            outcome = origin.allocator.outcomes[-1]
            assert [bid.robot for bid in outcome.awardable()] == ["r1", "r3"]
            # r2 is busy: it only says what the task would cost it later (optimal asks)
            assert [bid.robot for bid in outcome.later()] == ["r2"]

            await echo_follows(tree_a, node_a, [11, 12], "r2")
            await echo_follows(tree_b, node_b, [21, 22], "r1")
            assert node_a.execution is execution_a
            await finish(tree_a, node_a)
            await finish(tree_b, node_b)
            assert node_a.assignments == ["r2"]
            assert node_b.assignments == ["r1"]
            assert origin.mission_control.stats.lost == 0
            await tree_a.shutdown()
            await tree_b.shutdown()


def _junk() -> Iterator[tuple[bytes | None, list[bytes]]]:
    """(routing id, frames) a confused or hostile peer might send."""
    garbage = b"\xc1\xff\x00garbage"
    fake = msgspec.msgpack.encode([0, ["origin", "x"], ["r1", "mission_control"], None, 0])
    unknown = msgspec.msgpack.encode([0, ["evil", "x"], ["r1", "team"], {"type": "Nope"}, 0])
    for ident in (None, b"evil"):
        yield ident, [b""]
        yield ident, [garbage]
        yield ident, [b"M" + garbage]
        yield ident, [b"M", garbage]
        yield ident, [b"Z" + garbage]
        yield ident, [b"H" + b"not an endpoint"]
        yield ident, [b"H" + b"\xff\xfe"]
        yield ident, [b"M" + unknown]
        yield ident, [b"a", b"b", b"c", b"d"]
        yield ident, [os.urandom(64)]
    # A peer that says hello properly (from a port nobody listens on), then sends frames
    # it should not.
    yield b"evil", [b"H" + b"tcp://127.0.0.1:1"]
    yield b"evil", [b"M" + garbage]
    yield b"evil", [b"M" + fake]  # claims to be someone else
    yield b"evil", [b"M" + unknown]
    yield b"evil", [b"M" + os.urandom(200)]


def _send_junk(endpoint: str) -> None:
    ctx: zmq.Context[zmq.Socket[bytes]] = zmq.Context.instance()
    socks: dict[bytes | None, zmq.Socket[bytes]] = {}
    try:
        for ident, frames in _junk():
            sock = socks.get(ident)
            if sock is None:
                sock = socks[ident] = ctx.socket(zmq.DEALER)
                sock.setsockopt(zmq.LINGER, 2000)
                if ident is not None:
                    sock.setsockopt(zmq.ROUTING_ID, ident)
                sock.connect(endpoint)
            sock.send_multipart(frames)
    finally:
        for sock in socks.values():
            sock.close()  # lingers until the junk is out


def _count(path: Path, text: str) -> int:
    return path.read_text(errors="replace").count(text) if path.exists() else 0


async def test_malformed_frames_are_dropped_and_agents_keep_bidding(spawn: Any, logs: Path) -> None:
    with anyio.fail_after(30):
        procs = await spawn(spec("r1", 1.0), spec("r2", 2.0))
        r1 = procs[0]
        async with origin_agent(peers_of(procs)) as origin:
            await joined(origin, {"r1", "r2"})
            transport = origin.system.transport
            assert isinstance(transport, ZmqTransport)
            before = sum(transport.stats.by_reason.values())
            # Junk at a child robot and at the origin itself.
            await asyncio.to_thread(_send_junk, r1.endpoint)
            await asyncio.to_thread(_send_junk, transport.endpoint)
            await until(None, lambda: sum(transport.stats.by_reason.values()) >= before + 10)
            await until(None, lambda: _count(logs, "transport.dropped") >= 10)

            # Both keep working: r1 still bids, wins and runs the capability.
            tree, node = echo_mission(origin)
            await until(tree, running_on(node, "r1"))
            await echo_follows(tree, node, [5, 6], "r1")
            await finish(tree, node)
            assert r1.alive()
            assert {"r1", "r2"} <= origin.team.alive()
            assert origin.system.stats.escalations == 0
            await tree.shutdown()


def test_many_agents_share_one_process(tmp_path: Path) -> None:
    """``launch`` hosts several robots in one process, each on its own port."""
    with tempfile.TemporaryFile() as err:
        proc = AgentProcess(
            [spec(f"g{i}", float(i)) for i in range(3)], timeout=30.0, stderr=err.fileno()
        )
        try:
            assert sorted(proc.endpoints) == ["g0", "g1", "g2"]
            assert len(set(proc.endpoints.values())) == 3
            assert proc.robot == "g0"
            assert proc.endpoint == proc.endpoints["g0"]
        finally:
            proc.stop()
        assert proc.proc.returncode == 0


def test_spawn_agents_starts_groups_in_parallel() -> None:
    """The blocking API, for scripts and benchmarks: one process per group."""
    procs = spawn_agents([spec("s1", 1.0), [spec("s2", 2.0), spec("s3", 3.0)]], timeout=30.0)
    try:
        assert [p.robots for p in procs] == [["s1"], ["s2", "s3"]]
        assert all(p.alive() for p in procs)
    finally:
        for p in procs:
            p.stop()
    assert [p.proc.returncode for p in procs] == [0, 0]


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('{"robot": "r1", "colour": "red"}', "colour"),
        ('[{"robot": "r1"}, {"robot": "r2", "peer": {}}]', "peer"),
        ('{"robot": "r1", "config": {"tick_hzz": 5}}', "tick_hzz"),
        (
            '{"robot": "r1", "factory": "btcap.team.demo:implementations",'
            ' "factory_args": {"price": 1}}',
            "price",
        ),
        ('{"robot": "r1", "factory": "btcap.team.demo:nothing"}', "nothing"),
        ('{"robot": "r1", "log_level": "loud"}', "log_level"),
    ],
)
def test_a_bad_spec_is_refused_naming_the_key(
    capsys: pytest.CaptureFixture[str], text: str, key: str
) -> None:
    assert main([text]) == 2
    err = capsys.readouterr().err
    assert err.startswith("agent spec: ")
    assert key in err
    assert "Traceback" not in err


def test_a_bad_config_key_fails_before_any_process_starts() -> None:
    with pytest.raises(ValueError, match="tick_hzz"):
        AgentProcess(AgentSpec(robot="r1", config={"tick_hzz": 5.0}))


async def test_an_agent_that_fails_is_named_and_stops_its_process(logs: Path) -> None:
    """One agent of a process cannot bind: it is logged and printed with its robot, its
    neighbour is stopped, and the process exits with status 1 (no hang, no silence)."""
    bad = spec("g1", 1.0, bind="tcp://no-such-interface:*")
    exited = pytest.raises(RuntimeError, match=r"agent g0, g1 exited \(code 1\)")
    with logs.open("ab") as log_file, anyio.fail_after(30), exited:
        await open_agent([spec("g0", 1.0), bad], timeout=30.0, stderr=log_file.fileno())
    text = await anyio.Path(logs).read_text()
    assert "launch.agent_failed" in text
    assert "agent g1: ValueError: cannot bind 'tcp://no-such-interface:*'" in text


async def test_open_agent_stops_politely_and_reports_the_exit_code() -> None:
    with anyio.fail_after(30):
        async with await open_agent(spec("q1", 1.0), timeout=30.0) as proc:
            assert proc.alive()
            assert proc.endpoint.startswith("tcp://127.0.0.1:")
        assert proc.returncode == 0
        assert not proc.alive()
