"""MCAP recordings read back with the ``mcap`` library's own reader: typed channels with
their schemas, the same events as the JSON Lines recording of the same ``--fast`` run,
the same bytes twice, the converter equal to the direct recording, and a file cut short
still readable up to its last whole chunk."""

from __future__ import annotations

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

import btcap.cli
from btcap.cli import main
from btcap.monitor.channels import EVENT_TOPICS, LOG_TOPIC, log_line
from btcap.monitor.mcaprecord import McapRecorder
from btcap.monitor.record import RecordError, read_metadata, read_record
from btcap.monitor.replay import Replay
from btcap.monitor.scene import SCENE_TOPICS

SMALL = Path(__file__).parents[2] / "sim" / "data" / "small.yaml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same --fast run recorded twice as MCAP and once as JSON Lines."""
    base = tmp_path_factory.mktemp("runs")
    saved = btcap.cli.configure_logging
    btcap.cli.configure_logging = lambda level, json=False: None  # type: ignore[assignment]
    try:
        files = {}
        for name in ("one.mcap", "two.mcap", "run.jsonl"):
            out = base / name.replace(".", "-")
            args = ["run", str(SMALL), "--fast", "--quiet", "--out", str(out)]
            assert main([*args, "--record", str(base / name)]) == 0
            files[name] = base / name
    finally:
        btcap.cli.configure_logging = saved
    return files


def _messages(path: Path) -> tuple[Any, list[tuple[str, dict[str, Any]]]]:
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        msgs = [(ch.topic, json.loads(m.data)) for _, ch, m in reader.iter_messages()]
    return summary, msgs


def _typed(events: list[dict[str, Any]], kind: str | None = None) -> list[dict[str, Any]]:
    """The events (of ``kind``) as their typed channel holds them: world events without
    their poses, and none of poses alone."""
    out = []
    for ev in events:
        if kind is not None and ev["k"] != kind:
            continue
        if ev["k"] == "world":
            ev = {k: v for k, v in ev.items() if k != "poses"}
            if len(ev) == 2:
                continue
        out.append(ev)
    return out


def _poses(tf: dict[str, Any]) -> dict[str, list[float]]:
    return {
        t["child_frame_id"]: [t["translation"]["x"], t["translation"]["y"]]
        for t in tf["transforms"]
    }


@pytest.mark.slow
def test_channels_have_their_schemas_and_the_jsonl_events(runs: dict[str, Path]) -> None:
    summary, msgs = _messages(runs["one.mcap"])
    jsonl = read_record(runs["run.jsonl"])
    kinds = Counter(ev["k"] for ev in jsonl)
    assert {"tree", "states", "auction", "run", "team", "finished", "map", "world"} <= set(kinds)
    for ch in summary.channels.values():
        schema = summary.schemas[ch.schema_id]
        assert (ch.message_encoding, schema.encoding) == ("json", "jsonschema")
        if ch.topic == LOG_TOPIC:
            assert schema.name == "foxglove.Log"
        elif ch.topic in SCENE_TOPICS:  # the world drawn (test_mcap_world.py)
            assert schema.name == SCENE_TOPICS[ch.topic]["title"]
        else:
            kind = next(k for k, (topic, _) in EVENT_TOPICS.items() if topic == ch.topic)
            assert schema.name == EVENT_TOPICS[kind][1]["title"]
            assert json.loads(schema.data)["title"] == schema.name
            assert summary.statistics.channel_message_counts[ch.id] == len(_typed(jsonl, kind))
    # each /btcap/ message is its event as the JSON Lines recording has it, but a world
    # event's poses, which are on /tf alone (an event of poses alone is /tf alone)
    events = [m for topic, m in msgs if topic.startswith("/btcap/")]
    assert sorted(map(json.dumps, events)) == sorted(map(json.dumps, _typed(jsonl)))
    poses = [ev["poses"] for ev in jsonl if "poses" in ev]
    assert [_poses(m) for topic, m in msgs if topic == "/tf"] == poses
    assert read_record(runs["one.mcap"]) == jsonl  # in the stream's order, not by time
    # a chunk at least every 60 s of clock: a crash loses at most a minute of a live run
    assert summary.statistics.chunk_count >= jsonl[-1]["t"] // 60
    logs = [m for topic, m in msgs if topic == LOG_TOPIC]
    assert any("won by" in m["message"] for m in logs)
    assert {"level", "message", "name", "timestamp"} <= set(logs[0])


@pytest.mark.slow
def test_metadata_and_the_same_bytes_twice(runs: dict[str, Path]) -> None:
    assert runs["one.mcap"].read_bytes() == runs["two.mcap"].read_bytes()
    with runs["one.mcap"].open("rb") as f:
        (meta,) = list(make_reader(f).iter_metadata())
    assert meta.name == "btcap"
    assert meta.metadata["scenario"] == "small"
    assert {"seed", "strategy", "btcap_version", "settings"} <= set(meta.metadata)
    assert read_metadata(runs["run.jsonl"]) == {
        k: v for k, v in meta.metadata.items() if k != "btcap_version"
    }


@pytest.mark.slow
def test_the_converter_writes_what_the_run_recorded(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "converted.mcap"
    assert main(["replay", str(runs["run.jsonl"]), "--to-mcap", str(out)]) == 0
    assert out.read_bytes() == runs["one.mcap"].read_bytes()
    assert "wrote" in capsys.readouterr().out


@pytest.mark.slow
def test_a_replay_of_the_mcap_ends_as_the_jsonl_one(runs: dict[str, Path]) -> None:
    ends = []
    for name in ("one.mcap", "run.jsonl"):
        replay = Replay.open(runs[name])
        replay.seek(replay.end)
        state = replay.snapshot()
        ends.append({k: v for k, v in state.items() if k != "title"})
    assert ends[0] == ends[1]


@pytest.mark.slow
def test_a_file_cut_short_is_read_up_to_its_last_whole_chunk(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    events = read_record(runs["run.jsonl"])
    path = tmp_path / "killed.mcap"
    recorder = McapRecorder(path, {"scenario": "small"}, chunk_size=4096)
    try:
        for i in range(0, len(events), 10):
            recorder.write(events[i : i + 10])  # flushed after each batch: what a kill leaves
        data = path.read_bytes()  # not closed yet: no summary, no footer
    finally:
        recorder.close()
    cut = tmp_path / "cut.mcap"
    seen = []
    for size in (len(data), len(data) * 2 // 3, len(data) // 2):
        cut.write_bytes(data[: size - 7])  # mid-record, as a kill mid-write leaves it
        got = read_record(cut)
        assert got == events[: len(got)]
        seen.append(len(got))
    assert seen[0] >= seen[1] >= seen[2] > 0


_FILLS_UP = """
import json, resource, signal, sys
from pathlib import Path
from structlog.testing import capture_logs
from btcap.monitor.mcaprecord import McapRecorder
from btcap.monitor.record import read_record

signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails: EFBIG
events = read_record(Path(sys.argv[1]))
resource.setrlimit(resource.RLIMIT_FSIZE, (16384, 16384))  # the disk fills mid-run
with capture_logs() as logs:
    recorder = McapRecorder(Path(sys.argv[2]), {"scenario": "small"}, chunk_size=4096)
    for i in range(0, len(events), 10):
        recorder.write(events[i : i + 10])
    recorder.close()
print(json.dumps({"logs": [e for e in logs if e["event"] == "monitor.record_failed"],
                  "failed": recorder.failed}))
"""


def test_a_full_disk_ends_an_mcap_recording_said_once(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    """The SDK's writer is told its writes went well once one failed: the recorder says
    it once and stops, the SDK warns at no message after it, nothing is raised. (In a
    process of its own, whose files may grow to 16 KiB: the disk fills mid-run.)"""
    out = tmp_path / "run.mcap"
    done = subprocess.run(
        [sys.executable, "-c", _FILLS_UP, str(runs["run.jsonl"]), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    said = json.loads(done.stdout)
    assert [e["path"] for e in said["logs"]] == [str(out)], said
    assert said["failed"] == "File too large", said
    assert "foxglove" not in done.stderr.lower(), done.stderr  # no warning per message
    assert 0 < out.stat().st_size <= 16384


@pytest.mark.slow
@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full (a full disk)")
def test_an_mcap_recording_that_cannot_start_raises_and_leaves_nothing_open() -> None:
    with pytest.raises(OSError, match="No space left"):
        McapRecorder(Path("/dev/full"), {"scenario": "small"})


def test_a_file_that_is_not_mcap_is_refused_naming_it(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 3)
    with pytest.raises(RecordError, match=r"bad\.mcap: not a readable MCAP file"):
        read_record(bad)


def test_an_auction_nobody_took_is_logged_under_its_auctioneer() -> None:
    """Foxglove's Log panel shows each line's ``name``: an empty one reads ``[]``."""
    close = {"k": "auction", "phase": "close", "t": 1.0, "bids": [["spot1", 73.2]]}
    nobody = {**close, "id": "op#1~x#83", "auctioneer": "op#1~x", "winner": None}
    assert log_line(nobody)[1:2] == ("op#1~x",)  # a robot's name may hold '#' and '~'
    assert log_line({**nobody, "winner": "spot1"})[1:2] == ("spot1",)
