"""The simulated world in an MCAP recording, read back with the ``mcap`` library: the map
as ``foxglove.Grid``, poses as ``foxglove.FrameTransforms``, robots, objects and areas as
``foxglove.SceneUpdate``; each message fits its schema; counts follow the JSON Lines
recording of the same ``--fast`` run; the end matches the mission's result."""

from __future__ import annotations

import base64
import itertools
import json
from collections import Counter
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcap.reader import make_reader

from btcap.monitor import Monitor
from btcap.monitor.mcaprecord import McapRecorder
from btcap.monitor.monitor import FOLLOW_EVERY_S
from btcap.monitor.record import read_record
from btcap.monitor.scene import SCENE_TOPICS, Scene, map_messages
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running import worldfeed
from btcap.sim.running.metrics import MissionResult
from btcap.sim.running.runner import run_fast

SMALL = Path(__file__).parents[2] / "sim" / "data" / "small.yaml"


async def _record(path: Path) -> MissionResult:
    with anyio.fail_after(60):
        async with Monitor(port=None, record=path, title="small") as monitor:
            return await run_fast(load_scenario(SMALL), monitor=monitor)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, MissionResult]:
    base = tmp_path_factory.mktemp("world")
    result = anyio.run(_record, base / "run.mcap")
    anyio.run(_record, base / "run.jsonl")
    return base / "run.mcap", base / "run.jsonl", result


def _fits(value: Any, schema: dict[str, Any], where: str) -> None:
    """``value`` has the shape ``schema`` says: no field it does not name, every field
    it requires, numbers, strings and booleans where it says so (enough JSON Schema for
    the Foxglove schemas)."""
    kind = schema.get("type")
    if "enum" in schema:
        assert value in schema["enum"], where
    elif kind == "object":
        assert isinstance(value, dict), where
        props = schema.get("properties", {})
        assert set(schema.get("required", [])) <= set(value), where
        for k, v in value.items():
            assert k in props, f"{where}.{k}: not in the schema"
            _fits(v, props[k], f"{where}.{k}")
    elif kind == "array":
        assert isinstance(value, list), where
        for i, v in enumerate(value):
            _fits(v, schema["items"], f"{where}[{i}]")
    elif kind == "number":
        assert isinstance(value, int | float), where
        assert not isinstance(value, bool), where
    elif kind == "integer":
        assert isinstance(value, int), where
        assert not isinstance(value, bool), where
    elif kind in ("string", "boolean"):
        assert isinstance(value, str if kind == "string" else bool), where


@pytest.mark.slow
def test_the_world_is_drawn_in_foxglove_schemas(
    recorded: tuple[Path, Path, MissionResult],
) -> None:
    mcap, jsonl, result = recorded
    with mcap.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        msgs = [(ch.topic, json.loads(m.data)) for _, ch, m in reader.iter_messages()]
    assert summary is not None
    assert summary.statistics is not None
    topics = {ch.topic: ch for ch in summary.channels.values()}
    assert set(SCENE_TOPICS) <= set(topics)
    for topic, schema in SCENE_TOPICS.items():
        ch = topics[topic]
        name = summary.schemas[ch.schema_id].name
        assert name == schema["title"] == json.loads(summary.schemas[ch.schema_id].data)["title"]
        assert name in ("foxglove.Grid", "foxglove.SceneUpdate", "foxglove.FrameTransforms")
    for topic, m in msgs:
        if topic in SCENE_TOPICS:
            _fits(m, SCENE_TOPICS[topic], topic)
    events = read_record(jsonl)
    assert events == read_record(mcap)
    kinds = Counter(ev["k"] for ev in events)
    worlds = [ev for ev in events if ev["k"] == "world"]
    counts = summary.statistics.channel_message_counts
    expected = {
        "/map": kinds["map"],
        "/scene/areas": kinds["map"],
        "/tf": sum("poses" in ev for ev in worlds),
        "/scene/robots": sum("robots" in ev for ev in worlds),
        "/scene/objects": sum("objects" in ev for ev in worlds),
    }
    assert kinds["map"] == 1
    assert all(expected.values())
    assert {t: counts[topics[t].id] for t in expected} == expected

    # the grid is the map, bottom row first; every pose is on a free cell of it
    (grid,) = [m for t, m in msgs if t == "/map"]
    (map_ev,) = [ev for ev in events if ev["k"] == "map"]
    rows, cell = map_ev["rows"], map_ev["cell_m"]
    data = base64.b64decode(grid["data"])
    assert grid["column_count"] == len(rows[0])
    assert len(data) == grid["row_stride"] * len(rows)
    walls = [data[i * grid["row_stride"] + j * 4] < 100 for i in range(len(rows))
             for j in range(len(rows[0]))]  # fmt: skip
    assert walls == [ch == "#" for row in reversed(rows) for ch in row]
    robots = {r.name for r in load_scenario(SMALL).robots}
    frames = [{tf["child_frame_id"] for tf in m["transforms"]} for t, m in msgs if t == "/tf"]
    assert frames[0] == robots  # every robot at first, then those that moved
    assert all(f and f <= robots for f in frames)
    assert sum(map(len, frames)) < len(frames) * len(robots)
    for t, m in msgs:
        if t == "/tf":
            for tf in m["transforms"]:
                x, y = tf["translation"]["x"], tf["translation"]["y"]
                assert rows[len(rows) - 1 - int(y // cell)][int(x // cell)] != "#"

    # robots carry their label in their own frame; the objects end as the mission did
    last = {t: m for t, m in msgs if t in ("/scene/robots", "/scene/objects")}
    labels = {e["frame_id"]: e["texts"][0]["text"] for e in last["/scene/robots"]["entities"]}
    assert set(labels) == robots
    assert all(r in labels[r] for r in robots)
    status = Counter(
        next(kv["value"] for kv in e["metadata"] if kv["key"] == "status")
        for e in last["/scene/objects"]["entities"]
    )
    done = result.summary
    assert status["decontaminated"] == done["decontaminated"] > 0
    assert sum(n for s, n in status.items() if s != "hidden") == done["found"]
    identified = ("contaminated", "clean", "carried", "decontaminated")
    assert sum(status[s] for s in identified) == done["identified"]


def test_a_map_is_drawn_upside_up() -> None:
    """Row 0 of the map file is the top of the picture: the grid's last row."""
    ev = {"t": 2.5, "k": "map", "rows": ["#.", ".:"], "cell_m": 0.5,
          "start": [0.25, 0.25], "decon": [0.75, 0.75]}  # fmt: skip
    (t1, _, grid), (t2, _, areas) = map_messages(ev, 2_500_000_000)
    assert (t1, t2) == ("/map", "/scene/areas")
    assert grid["timestamp"] == {"sec": 2, "nsec": 500_000_000}
    pixels = base64.b64decode(grid["data"])
    assert [pixels[i * 4] for i in range(4)] == [235, 150, 60, 235]  # ". :" then "# ."
    assert grid["cell_size"] == {"x": 0.5, "y": 0.5}
    assert grid["column_count"] == 2
    assert [e["id"] for e in areas["entities"]] == ["decon", "start"]


def test_the_scene_is_drawn_whole_from_what_changed() -> None:
    """World events hold only the robots and objects that changed; each /scene message
    is still the whole picture (Foxglove draws a topic's last message alone after a
    seek), the same bytes as one drawn from a single event holding everything."""
    a, b = {"up": True, "task": "idle"}, {"up": True, "task": "explore"}
    o1 = {"id": 1, "x": 1.5, "y": 2.5, "status": "hidden", "by": None}
    o2 = {"id": 2, "x": 3.5, "y": 0.5, "status": "found", "by": None}
    scene = Scene()
    scene.draw({"t": 1.0, "k": "world", "robots": {"r1": a, "r2": a}, "objects": [o1, o2],
                "poses": {"r1": [0.5, 0.5], "r2": [1.5, 0.5]}}, 1_000_000_000)  # fmt: skip
    carried = {**o1, "status": "carried", "by": "r2"}
    drawn = scene.draw({"t": 2.0, "k": "world", "robots": {"r2": b}, "objects": [carried],
                        "poses": {"r2": [2.5, 0.5]}}, 2_000_000_000)  # fmt: skip
    whole = Scene().draw({"t": 2.0, "k": "world", "robots": {"r1": a, "r2": b},
                          "objects": [carried, o2]}, 2_000_000_000)  # fmt: skip
    assert [t for t, _, _ in drawn] == ["/tf", "/scene/robots", "/scene/objects"]
    assert drawn[1:] == whole
    (tf,) = [json.loads(data) for t, _, data in drawn if t == "/tf"]
    assert [f["child_frame_id"] for f in tf["transforms"]] == ["r2"]  # the robot that moved
    assert json.loads(scene.transforms(3_000_000_000))["transforms"][0]["translation"] == {
        "x": 0.5, "y": 0.5, "z": 0.0}  # fmt: skip
    assert scene.robots == {"r1": a, "r2": b}
    # a robot's entity is kept as JSON parts around its task and label: any text fits
    odd = {"up": False, "task": 'move "to" (1, 2)\n\u00e9'}
    (_, _, data), *_ = Scene().draw({"t": 0.0, "k": "world", "robots": {"r\u00e9": odd}}, 0)
    (entity,) = json.loads(data)["entities"]
    assert entity["frame_id"] == "r\u00e9"
    assert entity["texts"][0]["text"] == f"r\u00e9 (down)\n{odd['task']}"
    assert entity["metadata"] == [{"key": "state", "value": "down"},
                                  {"key": "task", "value": odd["task"]}]  # fmt: skip


@pytest.mark.slow
def test_world_events_hold_only_what_changed(
    recorded: tuple[Path, Path, MissionResult],
) -> None:
    """The first world event holds every robot, object and pose; each later one only
    those that changed since they were last sent."""
    worlds = [ev for ev in read_record(recorded[1]) if ev["k"] == "world"]
    robots = {r.name for r in load_scenario(SMALL).robots}
    first = {part: next(ev[part] for ev in worlds if part in ev) for part in
             ("robots", "objects", "poses")}  # fmt: skip
    assert set(first["robots"]) == set(first["poses"]) == robots
    last: dict[str, dict[Any, Any]] = {"objects": {}, "poses": {}}
    sent = {"objects": 0, "poses": 0}
    for ev in worlds:
        for o in ev.get("objects", []):
            assert last["objects"].get(o["id"]) != o  # only objects that changed
            last["objects"][o["id"]] = o
            sent["objects"] += 1
        for robot, xy in ev.get("poses", {}).items():
            assert last["poses"].get(robot) != xy  # only robots that moved
            last["poses"][robot] = xy
            sent["poses"] += 1
    with_objects = sum("objects" in ev for ev in worlds)
    assert sent["objects"] < with_objects * len(first["objects"])
    assert sent["poses"] < sum("poses" in ev for ev in worlds) * len(robots)


@pytest.mark.slow
def test_poses_are_thinned_out_and_end_exact(
    recorded: tuple[Path, Path, MissionResult],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Poses come at most every POSE_EVERY_S of the clock, unless a robot's task or an
    object changed in the same event (then the pose is exact); the last poses are where
    the robots ended, as a recording of every step has them."""
    worlds = [ev for ev in read_record(recorded[1]) if ev["k"] == "world"]
    poses = [ev for ev in worlds if "poses" in ev]
    gaps = [b["t"] - a["t"] for a, b in itertools.pairwise(poses)
            if "robots" not in b and "objects" not in b]  # fmt: skip
    assert gaps
    assert min(gaps) >= worldfeed.POSE_EVERY_S > FOLLOW_EVERY_S  # the monitor's batches
    monkeypatch.setattr(worldfeed, "POSE_EVERY_S", 0.0)  # every step a robot moved
    anyio.run(_record, tmp_path / "every.jsonl")
    every = [ev for ev in read_record(tmp_path / "every.jsonl") if "poses" in ev]
    assert len(every) > len(poses)
    # each event holds the robots that moved: added up, where all of them were then
    seen, seen_every = _poses_so_far(poses), _poses_so_far(every)
    assert seen_every[-1][1] == seen[-1][1]
    for t, where in seen:  # the same run: where the robots were then, as every step has it
        assert [w for u, w in seen_every if u <= t][-1] == where


def _poses_so_far(events: list[dict[str, Any]]) -> list[tuple[float, dict[str, Any]]]:
    so_far: dict[str, Any] = {}
    out = []
    for ev in events:
        so_far.update(ev["poses"])
        out.append((ev["t"], dict(so_far)))
    return out


@pytest.mark.slow
def test_robots_objects_and_areas_show_from_above(
    recorded: tuple[Path, Path, MissionResult],
) -> None:
    """Seen from above at the example layout's zoom (a 120 x 80 m cave, 3 to 4 pixels a
    metre) a drawing under a metre is a dot: robots, objects and the areas are drawn
    larger, a robot's label beside its sphere, not over it."""
    mcap = recorded[0]
    with mcap.open("rb") as f:
        msgs = [(ch.topic, json.loads(m.data)) for _, ch, m in make_reader(f).iter_messages()]
    sizes: dict[str, set[float]] = {"spheres": set(), "cubes": set()}
    for topic, m in msgs:
        if topic not in ("/scene/robots", "/scene/objects", "/scene/areas"):
            continue
        for entity in m["entities"]:
            for kind, found in sizes.items():
                found.update(min(p["size"]["x"], p["size"]["y"]) for p in entity.get(kind, []))
            if topic == "/scene/robots":
                label = entity["texts"][0]["pose"]["position"]
                assert abs(label["y"]) >= entity["spheres"][0]["size"]["y"]
    assert sizes["spheres"]
    assert sizes["cubes"]
    assert min(sizes["spheres"]) >= 2.0
    assert min(sizes["cubes"]) >= 1.5


async def test_a_robot_is_drawn_from_when_it_joins(tmp_path: Path) -> None:
    """dynamic.yaml's bebop1 joins at 30 s: the simulation has it idle at the start from
    the first step, the picture (its state, task and pose) only once it joined."""
    path = tmp_path / "run.mcap"
    scenario = load_scenario(SMALL.with_name("dynamic.yaml"))
    with anyio.fail_after(60):
        async with Monitor(port=None, record=path, title="dynamic") as monitor:
            await run_fast(scenario, monitor=monitor)
    events = read_record(path)
    (joined,) = [e["t"] for e in events if e["k"] == "team" and e["robot"] == "bebop1"][:1]
    assert joined >= 30
    seen = [
        e["t"]
        for e in events
        if e["k"] == "world" and ("bebop1" in e.get("robots", {}) or "bebop1" in e.get("poses", {}))
    ]
    assert seen
    assert seen[0] >= joined
    first = next(e for e in events if e["k"] == "world" and e["t"] == seen[0])
    assert first["robots"]["bebop1"]["up"]
    assert "bebop1" in first["poses"]  # where it stands as it joins
    with path.open("rb") as f:
        drawn = [
            (m.log_time / 1e9, [e["id"] for e in json.loads(m.data)["entities"]])
            for _, ch, m in make_reader(f).iter_messages(topics=["/scene/robots"])
        ]
    assert all("robot/bebop1" not in ids for t, ids in drawn if t < joined)
    assert any("robot/bebop1" in ids for t, ids in drawn)


def test_poses_alone_are_not_taken_for_an_earlier_world_event(tmp_path: Path) -> None:
    """A world event that draws nothing (on /btcap/world alone) and, next in the file, an
    event of poses alone at a later time (on /tf alone): two events read back, not one
    with the poses moved to the first one's time."""
    events = [
        {"t": 0.0, "k": "robot", "robot": "r1"},
        {"t": 10.0, "k": "world", "robots": {}},
        {"t": 12.0, "k": "world", "poses": {"r1": [1.0, 2.0]}},
        {"t": 12.0, "k": "world", "robots": {"r1": {"up": True, "task": "x"}}},
        {"t": 14.0, "k": "world", "poses": {"r1": [1.0, 4.0]}},
    ]
    path = tmp_path / "run.mcap"
    recorder = McapRecorder(path)
    for ev in events:
        recorder.write([ev])
    recorder.close()
    assert read_record(path) == events
