"""How a monitored run ends: the monitor says so (``finished``), a page is sent it before
the server closes, the recording ends with it and so does its replay."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import aiohttp
import anyio
import pytest

from btcap import Monitor, Replay
from btcap.monitor import read_record
from btcap.monitor.record import RecordError


async def test_finish_is_handed_on_at_once_after_the_changes_before_it(tmp_path: Path) -> None:
    record = tmp_path / "run.jsonl"
    with anyio.fail_after(10):
        async with Monitor(port=None, record=record, batch_hz=1) as monitor:
            monitor.emit({"t": 41.5, "k": "robot", "robot": "husky1"})
            monitor.finish("failed", "mission failed after 42 s")
            assert monitor.snapshot()["finished"] == {
                "t": 41.5, "result": "failed", "summary": "mission failed after 42 s"
            }  # fmt: skip
            with pytest.raises(ValueError, match="result 'done': expected one of succeeded"):
                monitor.finish("done", "?")
    events = read_record(record)
    assert [e["k"] for e in events] == ["robot", "finished"]  # stop() said nothing more


async def test_a_monitor_stopped_without_a_result_says_it_stopped(tmp_path: Path) -> None:
    record = tmp_path / "run.jsonl"
    with anyio.fail_after(10):
        async with Monitor(port=None, record=record) as monitor:
            monitor.emit({"t": 3.0, "k": "robot", "robot": "ada"})
    (end,) = [e for e in read_record(record) if e["k"] == "finished"]
    assert end == {"t": 3.0, "k": "finished", "result": "stopped",
                   "summary": "monitoring stopped"}  # fmt: skip


async def _until_closed(ws: aiohttp.ClientWebSocketResponse) -> list[dict[str, Any]]:
    got = []
    async for msg in ws:
        got.append(json.loads(msg.data))
    return got


async def test_a_page_is_sent_how_the_run_ended_before_the_server_closes() -> None:
    """stop() says the run stopped and closes the page at once: the page still gets the
    last changes and the end, then a clean close (not a dropped connection)."""
    with anyio.fail_after(20):
        monitor = Monitor(port=0, batch_hz=1)  # no batch of its own in between
        await monitor.start()
        try:
            async with aiohttp.ClientSession() as http, http.ws_connect(monitor.url + "ws") as ws:
                assert json.loads((await ws.receive()).data)["type"] == "snapshot"
                monitor.emit({"t": 1.0, "k": "robot", "robot": "ada"})
                async with anyio.create_task_group() as tg:
                    tg.start_soon(monitor.stop)
                    got = await _until_closed(ws)
                assert ws.close_code == aiohttp.WSCloseCode.OK
        finally:
            await monitor.stop()
    events = [e for m in got for e in m["events"]]
    assert [(e["k"], e.get("result")) for e in events] == [("robot", None), ("finished", "stopped")]


def _record(path: Path, events: list[dict[str, Any]]) -> Path:
    head = {"format": "btcap-monitor", "version": 1}
    path.write_text("".join(json.dumps(e) + "\n" for e in [head, *events]))
    return path


def test_a_replay_shows_how_the_run_ended_at_its_end_only(tmp_path: Path) -> None:
    end = {"t": 90.0, "k": "finished", "result": "stopped",
           "summary": "mission stopped after 90 s (interrupted)"}  # fmt: skip
    path = _record(tmp_path / "r.jsonl", [{"t": 0.0, "k": "robot", "robot": "a"}, end])
    replay = Replay.open(path)
    assert replay.snapshot()["finished"] is None
    replay.seek(replay.end)
    assert replay.snapshot()["finished"]["summary"] == end["summary"]
    replay.seek(45.0)
    assert replay.snapshot()["finished"] is None


def test_a_recorded_end_without_its_summary_is_refused_naming_the_line(tmp_path: Path) -> None:
    path = _record(tmp_path / "r.jsonl", [{"t": 1.0, "k": "finished", "result": "failed"}])
    with pytest.raises(RecordError, match=r"r.jsonl:2: a 'finished' event: no 'summary'"):
        read_record(path)
    path = _record(tmp_path / "r.jsonl", [{"t": 1.0, "k": "finished", "result": 7, "summary": "x"}])
    with pytest.raises(RecordError, match=r"r.jsonl:2: a 'finished' event: 'result' is 7"):
        read_record(path)
