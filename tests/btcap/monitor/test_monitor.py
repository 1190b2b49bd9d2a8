"""The monitor without a browser: its picture, /api/state, the WebSocket stream and its
batching, recordings and their replay (on explicit time where the subject allows)."""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import re
import warnings
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import aiohttp
import anyio
import pytest
from structlog.testing import capture_logs

import btcap.cli
from btcap import Leaf, Monitor, Parallel, ReactiveSequence, Replay, State, Tree
from btcap.actors import ManualClock
from btcap.cli import main
from btcap.cli.monitor import parse_address
from btcap.monitor import RecordError, read_record
from btcap.monitor.hub import BACKLOG, Hub
from btcap.monitor.server import MonitorServer
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

DATA = Path(__file__).parents[2] / "sim" / "data"
ROBOTS = {"husky1", "spot1", "bebop1"}
PICTURE = ("robots", "runs", "auctions", "marks", "finished")


async def _json(url: str) -> Any:
    async with aiohttp.ClientSession() as http, http.get(url) as resp:
        assert resp.status == 200
        assert "default-src 'self'" in resp.headers["Content-Security-Policy"]
        return await resp.json()


@pytest.fixture(scope="module")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path]:
    """The small mission on virtual time with a recording monitor: (live state, record)."""
    record = tmp_path_factory.mktemp("monitor") / "run.jsonl"

    async def main() -> dict[str, Any]:
        with anyio.fail_after(60):
            async with Monitor(port=0, record=record, title="small") as monitor:
                result = await run_fast(load_scenario(DATA / "small.yaml"), monitor=monitor)
                assert result.completed
                state: dict[str, Any] = await _json(monitor.url + "api/state")
                return state

    return asyncio.run(main()), record


def test_the_picture_shows_every_robot_its_trees_runs_and_auctions(
    small_run: tuple[dict[str, Any], Path],
) -> None:
    state, _ = small_run
    assert state["mode"] == "live"
    assert state["title"] == "small"
    robots = state["robots"]
    assert set(robots) == ROBOTS | {"operator"}
    assert all(r["status"] == "joined" for r in robots.values())
    for name in ROBOTS:
        assert list(robots[name]["trees"]) == [f"{name}-host"]
    mission = robots["operator"]["trees"]["find_and_decontaminate"]["nodes"]
    caps = {n["name"] for n in mission if n["cap"]}
    assert caps == {"explore", "identify", "decontaminate"}
    assert mission[0]["parent"] is None
    assert mission[0]["state"] == "succeeded"
    runs = state["runs"]
    assert {r["robot"] for r in runs} == ROBOTS  # everybody worked, lanes for all
    assert all(r["end"] is not None and r["end"] >= r["start"] for r in runs)
    explore = {r["robot"] for r in runs if r["capability"] == "Explore"}
    assert explore == {"bebop1"}  # the cheap explorer, as the bids say
    awarded = [a for a in state["auctions"] if a["winner"] is not None]
    assert awarded
    assert all(a["bids"][0][0] == a["winner"] for a in awarded)
    assert state["auctions"][0]["why"] == "first request"
    assert state["finished"]["result"] == "succeeded"
    assert re.fullmatch(r"mission succeeded after \d+ s", state["finished"]["summary"])


def test_replay_of_the_recording_ends_in_the_live_state(
    small_run: tuple[dict[str, Any], Path],
) -> None:
    live, record = small_run

    async def main() -> dict[str, Any]:
        replay = Replay.open(record, speed=1e9)
        server = MonitorServer(replay, "127.0.0.1", 0)
        with anyio.fail_after(30):
            await server.start()
            try:
                assert (await _json(server.url + "api/state"))["runs"] == []  # at the start
                replay.step(1.0)  # a second of wall time covers the whole run at this speed
                state: dict[str, Any] = await _json(server.url + "api/state")
                return state
            finally:
                await server.stop()

    replayed = asyncio.run(main())
    assert replayed["mode"] == "replay"
    assert replayed["replay"]["playing"] is False
    for key in PICTURE:
        assert replayed[key] == live[key], key


def test_seeking_back_and_forth_gives_the_picture_of_that_time(
    small_run: tuple[dict[str, Any], Path],
) -> None:
    _, record = small_run
    events = read_record(record)
    replay = Replay(events)
    middle = (replay.start + replay.end) / 2
    replay.seek(replay.end)
    replay.seek(middle)
    fresh = Replay(events)
    fresh.seek(middle)
    assert fresh.snapshot() == replay.snapshot()
    runs = replay.snapshot()["runs"]
    assert runs
    assert all(r["start"] <= middle for r in runs)
    assert any(r["end"] is None or r["end"] > middle for r in runs)  # as it was then


def test_a_failed_executor_shows_as_the_reason_of_the_re_auction(tmp_path: Path) -> None:
    record = tmp_path / "dynamic.jsonl"

    async def main() -> None:
        with anyio.fail_after(60):
            async with Monitor(port=None, record=record) as monitor:
                await run_fast(load_scenario(DATA / "dynamic.yaml"), monitor=monitor)

    asyncio.run(main())
    events = read_record(record)
    marks = {(e["robot"], e["change"]) for e in events if e["k"] == "team"}
    assert {("husky1", "failed"), ("bebop1", "joined"), ("bebop1", "left")} <= marks
    lost = [e for e in events if e["k"] == "run" and e["phase"] == "end" and e["result"] == "lost"]
    assert lost
    assert all("husky1" in e["why"] for e in lost)
    again = [e["why"] for e in events if e["k"] == "auction" and e["phase"] == "open"]
    gone = "re-auction: executor lost (husky1: robot husky1 failed"
    assert any(w.startswith(gone) for w in again)


# -- explicit time: one tree on a manual clock --------------------------------------------


class _Flip(Leaf):
    """Succeeds and fails by turns: a state change on every tick."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.n = 0

    def on_tick(self) -> State:
        self.n += 1
        return State.SUCCEEDED if self.n % 2 else State.FAILED


@pytest.fixture
async def flip_tree() -> AsyncIterator[Tree]:
    tree = Tree(ReactiveSequence("root", children=[_Flip("a")]), clock=ManualClock(5.0))
    tree.setup()
    yield tree
    await tree.shutdown()


async def test_changes_between_batches_are_sent_once_each_with_the_latest_state(
    flip_tree: Tree,
) -> None:
    with anyio.fail_after(10):
        async with Monitor(port=0) as monitor:
            monitor.add_tree(flip_tree, robot="r1")
            monitor.flush()
            async with aiohttp.ClientSession() as http, http.ws_connect(monitor.url + "ws") as ws:
                first = json.loads((await ws.receive()).data)
                assert first["type"] == "snapshot"
                assert first["state"]["robots"]["r1"]["trees"]["root"]["nodes"][1]["id"] == "root/a"
                for _ in range(1001):  # ends on a success
                    flip_tree.tick()
                await flip_tree.clock.advance(2.5)  # type: ignore[attr-defined]
                batch = monitor.flush()
                msg = json.loads((await ws.receive()).data)
    assert msg == {"type": "events", "events": batch}
    assert batch == [
        {
            "t": 7.5,
            "k": "states",
            "robot": "r1",
            "tree": "root",
            "states": {"root/a": "succeeded", "root": "succeeded"},
        }
    ]


async def test_the_stream_never_exceeds_the_batch_rate(flip_tree: Tree) -> None:
    """Every tick changes the tree; the page still gets at most ``batch_hz`` messages a
    second (a batch waits at least its period, however the machine is loaded)."""
    with anyio.fail_after(20):
        async with Monitor(port=0, batch_hz=20) as monitor:
            monitor.add_tree(flip_tree, robot="r1")
            async with aiohttp.ClientSession() as http, http.ws_connect(monitor.url + "ws") as ws:
                await ws.receive()  # the snapshot
                hub = monitor.hub
                loop = asyncio.get_running_loop()
                start, sent = loop.time(), hub.sent
                while hub.sent - sent < 10:
                    flip_tree.tick()
                    await asyncio.sleep(0)
                elapsed = loop.time() - start
                got = [json.loads((await ws.receive()).data) for _ in range(10)]
    assert all(m["type"] == "events" for m in got)
    assert elapsed * 20 + 1 >= 10  # ten batches took at least nine periods


async def test_a_tree_added_later_and_its_changing_shape_are_sent_whole(flip_tree: Tree) -> None:
    monitor = Monitor(port=None)
    monitor.add_tree(flip_tree, robot="r1")
    flip_tree.insert("root", _Flip("b"))
    flip_tree.tick()
    (ev,) = [e for e in monitor.flush() if e["k"] == "tree"][-1:]
    assert [n["id"] for n in ev["nodes"]] == ["root", "root/a", "root/b"]
    assert monitor.snapshot()["robots"]["r1"]["trees"]["root"]["nodes"][2]["state"] == "succeeded"


# -- recordings -------------------------------------------------------------------------------


_HEAD = '{"format": "btcap-monitor", "version": 1}\n'


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty file"),
        ('{"hello": 1}\n', ":1: not a btcap recording"),
        ('{\n  "pretty": "json"\n}\n', ":1: not a btcap recording"),
        ('{"format": "btcap-monitor", "version": 9}\n', ":1: recording version 9"),
        ('{"format": "btcap-monitor", "version": 1}\n[1]\n{"t": 0, "k": "x"}\n', ":2: not a JSON"),
        ('{"format": "btcap-monitor", "version": 1}\n{"k": "robot"}\n', ":2: an event needs"),
        (_HEAD + '{"t": 0, "k": "tree", "robot": "a"}\n', ":2: a 'tree' event: no 'nodes'"),
        (_HEAD + '{"t": 0, "k": "robot", "robot": ["a"]}\n', ":2: a 'robot' event: 'robot'"),
        (_HEAD + '{"t": 0, "k": "robot", "robot": 7}\n', ":2: a 'robot' event: 'robot'"),
        (
            _HEAD + '{"t": 0, "k": "tree", "robot": "a", "tree": "m", "nodes": [1]}\n',
            ":2: a 'tree'",
        ),
        (_HEAD + '{"t": true, "k": "robot", "robot": "a"}\n', ":2: an event needs"),
    ],
)
def test_a_bad_recording_is_refused_naming_the_line(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text(text)
    with pytest.raises(RecordError, match=message):
        read_record(path)


def test_a_recording_cut_off_mid_line_is_read_up_to_there(tmp_path: Path) -> None:
    path = tmp_path / "cut.jsonl"
    head = '{"format": "btcap-monitor", "version": 1}\n{"t": 1, "k": "robot", "robot": "a"}\n'
    path.write_text(head + '{"t": 2, "k": "rob')
    assert read_record(path) == [{"t": 1, "k": "robot", "robot": "a"}]


# -- the command line ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "address"),
    [("8765", ("127.0.0.1", 8765)), ("0.0.0.0:0", ("0.0.0.0", 0)), ("[::1]:99", ("::1", 99))],
)
def test_monitor_addresses(text: str, address: tuple[str, int]) -> None:
    assert parse_address(text) == address


@pytest.mark.parametrize("text", ["", "abc", "host:", "1:65536", "-1"])
def test_a_bad_monitor_address_is_refused_naming_it(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match="expected \\[HOST:\\]PORT"):
        parse_address(text)


def test_btcap_run_records_by_default_replay_plots_it_and_refuses_other_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)
    out = tmp_path / "run"
    assert main(["run", "--fast", "--quiet", "--out", str(out), str(DATA / "small.yaml")]) == 0
    events = read_record(out / "monitor.jsonl")
    assert {e["k"] for e in events} >= {"robot", "tree", "states", "team", "run", "auction"}
    assert [e["result"] for e in events if e["k"] == "finished"] == ["succeeded"]
    assert events[-1]["k"] == "finished"  # how it ended, last
    assert main(["replay", str(out / "result.json")]) == 2
    assert "result.json:1: not a btcap recording" in capsys.readouterr().err
    png = tmp_path / "timeline.png"
    assert main(["replay", str(out / "monitor.jsonl"), "--plot", str(png)]) == 0
    assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


# -- replay controls and slow pages --------------------------------------------------------


async def test_a_page_plays_pauses_and_seeks_a_replay(
    small_run: tuple[dict[str, Any], Path],
) -> None:
    _, record = small_run
    replay = Replay.open(record, speed=10.0)
    replay.playing = False
    server = MonitorServer(replay, "127.0.0.1", 0)
    with anyio.fail_after(30):
        await server.start()
        try:
            async with aiohttp.ClientSession() as http, http.ws_connect(server.url + "ws") as ws:
                first = json.loads((await ws.receive()).data)
                assert first["state"]["replay"]["t"] == replay.start
                await ws.send_str(json.dumps({"op": "seek", "t": replay.end}))
                again = json.loads((await ws.receive()).data)
                assert again["type"] == "snapshot"
                assert again["state"]["runs"] == replay.snapshot()["runs"] != []
                await ws.send_str(json.dumps({"op": "speed", "speed": 50}))
                faster = json.loads((await ws.receive()).data)
                await ws.send_str("not json")  # ignored
                await ws.send_str(json.dumps({"op": "play"}))  # at the end: from the start
                msgs = [json.loads((await ws.receive()).data) for _ in range(2)]
        finally:
            await server.stop()
    assert faster["events"] == [{"t": replay.end, "k": "clock", "playing": False, "speed": 50.0}]
    assert msgs[0]["type"] == "snapshot"
    assert msgs[0]["state"]["runs"] == []
    assert msgs[1]["events"] == [{"t": replay.start, "k": "clock", "playing": True, "speed": 50.0}]


async def test_a_page_that_falls_behind_gets_a_snapshot_not_a_backlog() -> None:
    hub = Hub()
    hub.snapshot = lambda: {"now": "the picture"}
    q = hub.join()
    for i in range(BACKLOG + 5):  # the 32nd finds the queue full
        hub.publish([{"t": i, "k": "robot", "robot": "r"}])
    got = [json.loads(q.get_nowait()) for _ in range(q.qsize())]
    assert got[0] == {"type": "snapshot", "state": {"now": "the picture"}}  # has 0..31
    assert [m["events"][0]["t"] for m in got[1:]] == list(range(BACKLOG, BACKLOG + 5))


async def test_pages_beyond_the_limit_are_refused_until_one_closes(
    small_run: tuple[dict[str, Any], Path],
) -> None:
    _, record = small_run
    server = MonitorServer(Replay.open(record), "127.0.0.1", 0, max_pages=2)
    with anyio.fail_after(30):
        await server.start()
        try:
            async with aiohttp.ClientSession() as http:
                url = server.url + "ws"
                async with http.ws_connect(url) as one, http.ws_connect(url):
                    assert json.loads((await one.receive()).data)["type"] == "snapshot"
                    while server.pages < 2:  # noqa: ASYNC110 - noted once set up
                        await anyio.sleep(0.01)
                    with pytest.raises(aiohttp.WSServerHandshakeError, match="503"):
                        await http.ws_connect(url)
                while server.pages:  # noqa: ASYNC110 - the server notes closes on its own
                    await anyio.sleep(0.01)
                async with http.ws_connect(url) as again:  # two closed: room again
                    assert json.loads((await again.receive()).data)["type"] == "snapshot"
        finally:
            await server.stop()


async def test_other_sites_cannot_read_a_loopback_monitor() -> None:
    """Not by DNS rebinding (another host name) nor by a WebSocket from their pages."""
    with anyio.fail_after(10):
        async with Monitor(port=0) as monitor, aiohttp.ClientSession() as http:
            url = monitor.url + "api/state"
            async with http.get(url, headers={"Host": "evil.example"}) as resp:
                assert resp.status == 403
            async with http.get(url, headers={"Host": "localhost"}) as resp:
                assert resp.status == 200
            evil = {"Origin": "http://evil.example"}
            with pytest.raises(aiohttp.WSServerHandshakeError, match="403"):
                await http.ws_connect(monitor.url + "ws", headers=evil)
            own = {"Origin": monitor.url.rstrip("/")}
            async with http.ws_connect(monitor.url + "ws", headers=own) as ws:
                assert json.loads((await ws.receive()).data)["type"] == "snapshot"


async def test_a_slot_shows_the_run_it_hosts_while_it_runs() -> None:
    net = InProcessNetwork(protocol_registry())
    cfg = AgentConfig(heartbeat_s=0.05, failure_timeout_s=5.0, auction_window_s=5.0)
    impls = implementations("scout", cost=1.0)  # echoes until told to stop
    with anyio.fail_after(30):
        async with (
            Agent("base", transport=net.transport("base"), config=cfg) as base,
            Agent(
                "scout", transport=net.transport("scout"), implementations=impls, config=cfg
            ) as scout,
        ):
            monitor = Monitor(port=None)
            monitor.add_agent(scout)
            for _ in range(1000):
                if base.repository.providers(ECHO.identity) == {"scout"}:
                    break
                await asyncio.sleep(0.01)
            echo = ECHO.node_type()("echo", inputs={"value": 3})
            tree = base.mission(ReactiveSequence("mission", children=[echo]))
            for _ in range(1000):  # the root is running as soon as the echo is unassigned
                tree.tick()
                if echo.state is State.RUNNING:
                    break
                await asyncio.sleep(0.01)
            monitor.flush()
            hosting = monitor.snapshot()["robots"]["scout"]["trees"]["scout-host"]["nodes"]
            echo.set_input("stop", True)
            done = (State.SUCCEEDED, State.FAILED)
            assert await tree.run(50, until=lambda s: s in done) is State.SUCCEEDED
            for _ in range(100):  # the slot puts the run down at its next tick
                monitor.flush()
                after = monitor.snapshot()["robots"]["scout"]["trees"]["scout-host"]["nodes"]
                if len(after) == 1:
                    break
                await asyncio.sleep(0.01)
            await tree.shutdown()
            monitor.detach()
    by_id = {n["id"]: n for n in hosting}
    assert by_id["slot/echo_impl"]["parent"] == "slot"
    assert by_id["slot/echo_impl/echo"]["state"] == "running"
    assert [n["id"] for n in after] == ["slot"]


async def test_an_auction_says_why_the_cheapest_bidder_did_not_win() -> None:
    """Two tasks at once: the cheap robot takes one, the other goes to the dear robot,
    and the monitor says why the cheap one was passed over there."""
    net = InProcessNetwork(protocol_registry())
    cfg = AgentConfig(heartbeat_s=0.05, failure_timeout_s=5.0, auction_window_s=5.0)

    def agent(name: str, cost: float | None = None) -> Agent:
        impls = implementations(name, cost=cost, duration_s=0.2) if cost is not None else []
        return Agent(name, transport=net.transport(name), implementations=impls, config=cfg)

    monitor = Monitor(port=None)
    with anyio.fail_after(30):
        async with agent("base") as base, agent("cheap", 1.0), agent("dear", 5.0):
            monitor.add_agent(base)
            team = {"cheap", "dear"}
            for _ in range(1000):  # both known and alive: the two auctions are one round
                if base.repository.providers(ECHO.identity) == team <= base.team.alive():
                    break
                await asyncio.sleep(0.01)
            echoes = [ECHO.node_type()(f"echo_{k}", inputs={"value": k}) for k in (1, 2)]
            tree = base.mission(Parallel("mission", children=echoes))
            done = (State.SUCCEEDED, State.FAILED)
            assert await tree.run(50, until=lambda s: s in done) is State.SUCCEEDED
            monitor.detach()
            await tree.shutdown()
    # (later auctions may re-evaluate running work: the first two are the round)
    auctions = [a for a in monitor.snapshot()["auctions"] if a["why"] == "first request"]
    assert sorted(a["winner"] for a in auctions) == ["cheap", "dear"]
    (second,) = [a for a in auctions if a["winner"] == "dear"]
    assert second["bids"][0] == ["cheap", 1.0]
    assert second["reasons"] == {"cheap": "took another task of the same round"}


async def test_a_monitor_that_cannot_listen_closes_its_recording(tmp_path: Path) -> None:
    """The port is taken: start fails, and the recording it opened is not left open."""
    with anyio.fail_after(10):
        async with Monitor(port=0) as taken:
            port = int(taken.url.rstrip("/").rsplit(":", 1)[1])
            monitor = Monitor(port=port, record=tmp_path / "run.jsonl")
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", ResourceWarning)
                with pytest.raises(OSError, match=f"cannot listen on 127.0.0.1:{port}"):
                    await monitor.start()
                del monitor
                gc.collect()
    assert [w for w in caught if issubclass(w.category, ResourceWarning)] == []


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (a full disk)")
async def test_a_full_disk_stops_the_recording_not_the_monitor() -> None:
    with anyio.fail_after(10), capture_logs() as logs:
        async with Monitor(port=None, record="/dev/full") as monitor:
            for k, robot in enumerate(["a", "b"]):
                monitor.emit({"t": float(k), "k": "robot", "robot": robot})
                assert len(monitor.flush()) == 1
    assert sorted(monitor.view.robots) == ["a", "b"]
    failed = [e for e in logs if e["event"] == "monitor.record_failed"]
    assert [e["path"] for e in failed] == ["/dev/full"], logs
