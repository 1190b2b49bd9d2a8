"""The live Foxglove server (``--foxglove``): a WebSocket client speaking the SDK's
subprotocol connects while a ``--fast`` run goes on, subscribes to every channel it is
advertised and receives on each what the MCAP recording of the same run holds."""

from __future__ import annotations

import json
import re
import socket
import struct
from collections import Counter
from pathlib import Path

import anyio
import pytest

import btcap.cli
from btcap.cli import main
from btcap.monitor import Monitor
from btcap.monitor.channels import EVENT_TOPICS
from btcap.monitor.scene import SCENE_TOPICS
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast

websockets = pytest.importorskip("websockets")

SMALL = Path(__file__).parents[2] / "sim" / "data" / "small.yaml"
#: The SDK's server (foxglove-sdk 0.30) speaks the Foxglove WebSocket protocol under this
#: name and refuses the older ``foxglove.websocket.v1``.
SUBPROTOCOL = "foxglove.sdk.v1"
_MESSAGE_DATA = 1  # a binary frame's opcode
#: Channels advertised before anything is sent: every event kind's, the log, the scene.
ADVERTISED = len(EVENT_TOPICS) + 1 + len(SCENE_TOPICS)


async def _watch(
    ws: object, topics: dict[int, str], got: Counter[str], kept: dict[str, bytes] | None = None
) -> None:
    """Subscribe to every channel advertised; count the messages of each (and keep the
    first of each in ``kept``)."""
    async for frame in ws:  # type: ignore[attr-defined]
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg["op"] == "advertise":
                subs = []
                for ch in msg["channels"]:
                    sub = len(topics) + 1
                    topics[sub] = ch["topic"]
                    subs.append({"id": sub, "channelId": ch["id"]})
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))  # type: ignore[attr-defined]
        elif frame[0] == _MESSAGE_DATA:
            (sub,) = struct.unpack_from("<I", frame, 1)
            got[topics[sub]] += 1
            if kept is not None:
                kept.setdefault(topics[sub], frame[13:])  # after the subscription, the time


@pytest.mark.slow
async def test_a_client_receives_every_channel_during_a_run(tmp_path: Path) -> None:
    record = tmp_path / "run.mcap"
    topics: dict[int, str] = {}
    got: Counter[str] = Counter()
    with anyio.fail_after(60):
        async with (
            Monitor(port=None, record=record, foxglove=("127.0.0.1", 0)) as monitor,
            websockets.connect(
                f"ws://127.0.0.1:{monitor.live.port}", subprotocols=[SUBPROTOCOL]
            ) as ws,
            anyio.create_task_group() as tg,
        ):
            tg.start_soon(_watch, ws, topics, got)
            # the server has every subscription before the run: no message is missed
            while len(topics) < ADVERTISED or monitor.live.subscriptions < len(topics):  # noqa: ASYNC110 - counters (one on the SDK's thread), no event to wait on
                await anyio.sleep(0.01)
            await run_fast(load_scenario(SMALL), monitor=monitor)
            monitor.flush()
            sent = monitor.live.sent
            while sum(got.values()) < sent:  # noqa: ASYNC110 - a counter, no event to wait on
                await anyio.sleep(0.01)
            tg.cancel_scope.cancel()
    from mcap.reader import make_reader

    with record.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert summary.statistics is not None
    recorded = {
        ch.topic: summary.statistics.channel_message_counts[ch.id]
        for ch in summary.channels.values()
    }
    assert set(topics.values()) == set(recorded)  # advertised up front: every channel
    assert dict(got) == recorded  # before the run's end: the monitor still served


@pytest.mark.slow
async def test_a_client_that_comes_late_is_sent_the_whole_picture() -> None:
    """/tf and /btcap/world hold what changed; a client that subscribes after the run
    is sent every robot's pose and every robot and object, not the last change alone."""
    kept: dict[str, bytes] = {}
    scenario = load_scenario(SMALL)
    with anyio.fail_after(60):
        async with Monitor(port=None, foxglove=("127.0.0.1", 0)) as monitor:
            await run_fast(scenario, monitor=monitor)
            monitor.flush()
            async with (
                websockets.connect(
                    f"ws://127.0.0.1:{monitor.live.port}", subprotocols=[SUBPROTOCOL]
                ) as ws,
                anyio.create_task_group() as tg,
            ):
                tg.start_soon(_watch, ws, {}, Counter(), kept)
                while not {"/tf", "/btcap/world", "/scene/objects"} <= set(kept):  # noqa: ASYNC110 - frames on the socket, no event to wait on
                    await anyio.sleep(0.01)
                tg.cancel_scope.cancel()
    robots = {r.name for r in scenario.robots}
    tf = json.loads(kept["/tf"])
    assert {t["child_frame_id"] for t in tf["transforms"]} == robots
    world = json.loads(kept["/btcap/world"])
    assert set(world["robots"]) == robots
    drawn = json.loads(kept["/scene/objects"])["entities"]
    assert sorted(o["id"] for o in world["objects"]) == sorted(
        int(e["id"].split("/")[1]) for e in drawn
    )


@pytest.mark.slow
def test_run_serves_foxglove_on_loopback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)
    args = ["run", str(SMALL), "--fast", "--quiet", "--no-record", "--out", str(tmp_path)]
    assert main([*args, "--foxglove", "0"]) == 0
    assert "foxglove: ws://127.0.0.1:" in capsys.readouterr().out


def test_a_foxglove_address_that_cannot_be_bound_is_named_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        args = ["run", str(SMALL), "--fast", "--quiet", "--no-record", "--out", str(tmp_path)]
        assert main([*args, "--foxglove", str(port)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"btcap: error: the Foxglove server cannot listen on 127.0.0.1:{port}: ")
    assert "address already in use" in err.lower()
    assert err.count("\n") == 1


def test_the_example_layout_is_current_and_shows_our_channels() -> None:
    """examples/foxglove/btcap.json is what make_layout.py makes, and every topic its
    panels read is one btcap sends."""
    import importlib.util

    root = Path(__file__).parents[3] / "examples" / "foxglove"
    spec = importlib.util.spec_from_file_location("make_layout", root / "make_layout.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    text = (root / "btcap.json").read_text()
    assert text == module.render()
    ours = {"/log", *SCENE_TOPICS, *(topic for topic, _ in EVENT_TOPICS.values())}
    read = set(re.findall(r'"(/[a-z/]+)', text))
    assert {"/map", "/scene/robots", "/log", "/btcap/auctions", "/btcap/world"} <= read <= ours


@pytest.mark.slow
async def test_a_replay_plays_to_foxglove(tmp_path: Path) -> None:
    """``btcap replay --foxglove``: a recording played on sends a client every channel's
    messages, as many as the MCAP recording of the same events holds."""
    from mcap.reader import make_reader

    from btcap.cli.monitor import _foxglove
    from btcap.monitor.mcaprecord import McapRecorder
    from btcap.monitor.record import read_record
    from btcap.monitor.replay import Replay

    with anyio.fail_after(60):
        async with Monitor(port=None, record=tmp_path / "run.jsonl") as monitor:
            await run_fast(load_scenario(SMALL), monitor=monitor)
    events = read_record(tmp_path / "run.jsonl")
    recorder = McapRecorder(tmp_path / "run.mcap")
    recorder.write(events)
    recorder.close()
    with (tmp_path / "run.mcap").open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert summary.statistics is not None
    recorded = {ch.topic: summary.statistics.channel_message_counts[ch.id]
                for ch in summary.channels.values()}  # fmt: skip
    topics: dict[int, str] = {}
    got: Counter[str] = Counter()
    replay = Replay(events)
    live = _foxglove(("127.0.0.1", 0))
    try:
        with anyio.fail_after(60):
            async with (
                websockets.connect(f"ws://127.0.0.1:{live.port}", subprotocols=[SUBPROTOCOL]) as ws,
                anyio.create_task_group() as tg,
            ):
                tg.start_soon(_watch, ws, topics, got)
                while len(topics) < ADVERTISED or live.subscriptions < len(topics):  # noqa: ASYNC110 - counters (one on the SDK's thread), no event to wait on
                    await anyio.sleep(0.01)
                replay.add_sink(live.write)  # the events at the start, then as it plays
                while replay.playing:
                    replay.step(10.0)  # the play's pace is the replay's: on, step by step
                while sum(got.values()) < live.sent:  # noqa: ASYNC110 - a counter, no event to wait on
                    await anyio.sleep(0.01)
                tg.cancel_scope.cancel()
    finally:
        live.close()
    assert dict(got) == recorded
