"""Child agents with CURVE keys from their :class:`AgentSpec`: members auction over an
encrypted channel, a keyless origin gets nothing through, bad key files are named.

Loopback only; every child process is killed at teardown.
"""

from __future__ import annotations

import asyncio
import shutil
from collections.abc import AsyncIterator, Callable
from pathlib import Path

import anyio
import msgspec
import pytest
import zmq
import zmq.asyncio
from zmq.utils.monitor import recv_monitor_message

from btcap import ReactiveSequence as SequenceNode
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.team.demo import ECHO
from btcap.team.deployment.launch import AgentProcess, AgentSpec, main
from btcap.team.deployment.spawn import AsyncAgentProcess, open_agent
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import KeyPair, TeamKeys, ZmqTransport
from btcap.transports.security import write_key_pair

pytestmark = pytest.mark.slow

LOCAL = "tcp://127.0.0.1:*"
TICK_S = 0.01
#: Heartbeats every 0.1 s, but nothing judged by a short wall time: on a machine loaded 15
#: deep on 2 cores a process can be held off for seconds, and a 1 s auction window or a
#: 0.5 s award or failure timeout would then decide the outcome. Auctions still close as
#: soon as every robot answered, so a quiet run is as fast as before.
TIMING: dict[str, float] = {
    "heartbeat_s": 0.1,
    "failure_timeout_s": 10.0,
    "auction_window_s": 10.0,
    "award_timeout_s": 10.0,
}
QUICK = msgspec.convert(TIMING, AgentConfig)


@pytest.fixture
def keys(tmp_path: Path) -> Path:
    """Certificates for origin and c1 in ``tmp_path``; ``tmp_path/team`` holds their
    public keys (the allow-list)."""
    team = tmp_path / "team"
    team.mkdir()
    for name in ("origin", "c1"):
        public, _ = write_key_pair(tmp_path, name)
        shutil.copy(public, team / public.name)
    return tmp_path


def child_spec(folder: Path, **changes: str) -> AgentSpec:
    spec = AgentSpec(
        robot="c1",
        factory="btcap.team.demo:implementations",
        factory_args={"cost": 1.0},
        keys=str(folder / "c1.key_secret"),
        trusted=str(folder / "team"),
        config=dict(TIMING),
    )
    return msgspec.structs.replace(spec, **changes)


@pytest.fixture
async def child(keys: Path, tmp_path: Path) -> AsyncIterator[AsyncAgentProcess]:
    with (tmp_path / "child.log").open("ab") as log_file:
        proc = await open_agent(child_spec(keys), timeout=30.0, stderr=log_file.fileno())
        try:
            yield proc
        finally:
            await proc.kill()


def agent(name: str, peers: dict[str, str], keys: Path | None) -> Agent:
    reg = protocol_registry()
    transport = ZmqTransport(
        name,
        LOCAL,
        reg,
        peers=peers,
        keys=None if keys is None else KeyPair.load(keys / f"{name}.key_secret"),
        trusted=None if keys is None else TeamKeys.load(keys / "team"),
    )
    return Agent(name, transport=transport, registry=reg, config=QUICK)


async def handshake_fails_without_keys(endpoint: str) -> None:
    """A keyless ZeroMQ client's handshake with ``endpoint`` is rejected (ZMTP mechanism
    mismatch), seen from the client's own socket monitor."""
    ctx = zmq.asyncio.Context()
    sock = ctx.socket(zmq.DEALER)
    monitor = sock.get_monitor_socket(zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL)
    try:
        sock.connect(endpoint)
        event = await recv_monitor_message(monitor)
        assert event["event"] == zmq.EVENT_HANDSHAKE_FAILED_PROTOCOL
    finally:
        sock.disable_monitor()
        monitor.close(0)
        sock.close(0)
        ctx.term()


async def until(tree: Tree, cond: Callable[[], bool]) -> None:
    """Tick ``tree`` until ``cond()``; the caller bounds it with fail_after."""
    while True:
        tree.tick()
        if cond():
            return
        await asyncio.sleep(TICK_S)


async def test_members_auction_over_curve_and_a_keyless_origin_is_shut_out(
    keys: Path, child: AsyncAgentProcess
) -> None:
    with anyio.fail_after(120):  # a hang; the run takes ~2 s on a quiet machine
        async with agent("origin", {"c1": child.endpoint}, keys) as origin:
            node = ECHO.node_type()("echo", inputs={"value": 3})
            tree = origin.mission(SequenceNode("root", children=[node]))
            await until(tree, lambda: node.state is State.RUNNING and node.outputs["value"] == 3)
            assert node.execution is not None
            assert node.execution.robot == "c1"
            assert origin.allocator.stats.early_closes >= 1

            await handshake_fails_without_keys(child.endpoint)
            async with agent("plain", {"c1": child.endpoint}, None) as plain:
                lone = ECHO.node_type()("echo", inputs={"value": 5})
                lone_tree = plain.mission(SequenceNode("root", children=[lone]))
                # Long enough for several hellos, heartbeats and auction windows.
                for _ in range(50):
                    lone_tree.tick()
                    await asyncio.sleep(TICK_S)
                assert "c1" not in plain.team.alive()
                assert plain.repository.providers(ECHO.identity) == frozenset()
                assert lone.execution is None
                assert not lone.assignments
                await lone_tree.shutdown()

            assert "c1" in origin.team.alive()  # the member's channel was never disturbed
            node.set_input("stop", True)
            await until(tree, lambda: tree.root.state is State.SUCCEEDED)
            assert node.assignments == ["c1"]
            await tree.shutdown()


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"keys": "/no/such.key_secret"}, "'c1': keys: /no/such.key_secret: no such"),
        ({"trusted": "/no/such/dir"}, "'c1': trusted: /no/such/dir: no such directory"),
        ({"trusted": ""}, "'c1': trusted: required with CURVE"),
    ],
)
def test_a_bad_key_field_is_named_before_any_process_starts(
    keys: Path, fields: dict[str, str], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        AgentProcess(child_spec(keys, **fields))


def test_a_team_directory_without_the_robots_own_key_is_refused(keys: Path) -> None:
    (keys / "team" / "c1.key").unlink()
    with pytest.raises(ValueError, match=r"'c1': trusted: .* holds no c1\.key"):
        AgentProcess(child_spec(keys))


def test_the_launcher_names_a_bad_key_file_without_a_traceback(
    keys: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = child_spec(keys, keys=str(keys / "c1.key"))  # the public half
    assert main([msgspec.json.encode(spec).decode()]) == 2
    err = capsys.readouterr().err
    assert "'c1': keys:" in err
    assert "holds no secret key" in err
    assert "Traceback" not in err
