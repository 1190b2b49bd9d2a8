"""Recordings that break off or hold odd times: what a replay or a conversion could read
is said in one line naming the file (never dropped unsaid), and every time a JSON Lines
recording holds converts to MCAP and back."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import msgspec
import pytest
from mcap.reader import make_reader

from btcap.cli import main
from btcap.monitor.mcaprecord import McapRecorder
from btcap.monitor.record import FORMAT, VERSION, read_record, read_recording

Event = dict[str, Any]


def _events(n: int, t0: float = 0.0) -> list[Event]:
    """A robot that joins, drives for ``n`` seconds of the clock and is done."""
    out: list[Event] = [
        {"t": t0, "k": "robot", "robot": "r1"},
        {"t": t0, "k": "team", "robot": "r1", "change": "joined"},
    ]
    for i in range(1, n + 1):
        out.append({"t": t0 + i, "k": "world", "poses": {"r1": [float(i), 2.0]}})
        out.append({"t": t0 + i, "k": "team", "robot": "r1", "change": "joined"})
    out.append({"t": t0 + n + 1, "k": "finished", "result": "succeeded", "summary": "done"})
    return out


def _mcap(path: Path, events: list[Event], *, close: bool = True) -> bytes:
    """``events`` recorded in small chunks, a batch a second; the bytes on disk before
    the file is closed (what a kill leaves) unless ``close``."""
    recorder = McapRecorder(path, {"scenario": "test"}, chunk_size=2048)
    try:
        for i in range(0, len(events), 4):
            recorder.write(events[i : i + 4])
        if not close:
            return path.read_bytes()
    finally:
        recorder.close()
    return path.read_bytes()


def _jsonl(path: Path, events: list[Event]) -> bytes:
    head = msgspec.json.encode({"format": FORMAT, "version": VERSION})
    data = b"\n".join([head, *map(msgspec.json.encode, events)]) + b"\n"
    path.write_bytes(data)
    return data


def test_a_killed_mcap_recording_says_what_it_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    events = _events(300)
    killed = tmp_path / "killed.mcap"
    data = _mcap(tmp_path / "live.mcap", events, close=False)
    killed.write_bytes(data[:-5])  # inside the chunk being written
    got, cut = read_recording(killed)
    assert 0 < len(got) < len(events)
    assert got == events[: len(got)]
    assert cut is not None
    assert cut.startswith(f"{killed}: cut short")
    assert f"read {len(got)} events, up to {got[-1]['t']:.1f} s" in cut
    assert main(["replay", str(killed), "--to-mcap", str(tmp_path / "out.mcap")]) == 0
    err = capsys.readouterr().err
    assert err == f"btcap: warning: {cut}\n"


def test_a_damaged_chunk_is_said_not_taken_for_the_end(tmp_path: Path) -> None:
    """A byte changed inside a chunk of a whole file: the events up to it, and where."""
    events = _events(300)
    whole = tmp_path / "whole.mcap"
    data = bytearray(_mcap(whole, events))
    assert read_recording(whole) == (events, None)
    with whole.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    damaged = tmp_path / "damaged.mcap"
    data[chunk.chunk_start_offset + chunk.chunk_length - chunk.compressed_size // 2] ^= 0x40
    damaged.write_bytes(data)
    got, cut = read_recording(damaged)
    assert len(got) < len(events)
    assert got == events[: len(got)]
    assert cut is not None
    assert cut.startswith(f"{damaged}: damaged at byte ")


def test_a_summary_cut_short_loses_no_event(tmp_path: Path) -> None:
    events = _events(50)
    path = tmp_path / "run.mcap"
    data = _mcap(path, events)
    path.write_bytes(data[:-20])  # in the footer: every message is before it
    got, cut = read_recording(path)
    assert got == events
    assert cut is not None
    assert "every message was read" in cut


def test_a_jsonl_line_cut_short_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    events = _events(5)
    path = tmp_path / "run.jsonl"
    data = _jsonl(path, events)
    path.write_bytes(data[:-10])
    got, cut = read_recording(path)
    assert got == events[:-1]
    lines = len(events) + 1
    assert cut == (
        f"{path}: line {lines} is cut short (a run that was killed?), skipped; "
        f"read {len(got)} events, up to {got[-1]['t']:.1f} s"
    )
    assert main(["replay", str(path), "--to-mcap", str(tmp_path / "out.mcap")]) == 0
    assert capsys.readouterr().err == f"btcap: warning: {cut}\n"
    assert read_record(tmp_path / "out.mcap") == got


@pytest.mark.parametrize("t0", [-5.0, 1e300], ids=["negative", "past-2554"])
def test_any_time_converts_to_mcap_and_back(t0: float, tmp_path: Path) -> None:
    """MCAP's log time is unsigned 64-bit nanoseconds: a time outside it is clamped there,
    and the event (poses alone included) comes back with its own time."""
    events = [*_events(3, t0), {"t": t0, "k": "other-kind", "x": 1}]
    jsonl, mcap = tmp_path / "run.jsonl", tmp_path / "run.mcap"
    _jsonl(jsonl, events)
    assert main(["replay", str(jsonl), "--to-mcap", str(mcap)]) == 0
    assert read_recording(mcap) == (events, None)


def test_whole_lines_without_the_end_of_the_run_are_said(tmp_path: Path) -> None:
    """A run killed between two writes leaves whole lines, and no ``finished`` event,
    which a monitor that stops always records."""
    events = _events(5)[:-1]
    path = tmp_path / "run.jsonl"
    _jsonl(path, events)
    got, cut = read_recording(path)
    assert got == events
    assert cut == (
        f"{path}: holds no end of the run (no 'finished' event: a run that was killed?); "
        f"read {len(events)} events, up to 5.0 s"
    )
