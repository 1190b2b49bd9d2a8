"""btcap's ``foxglove.*`` JSON Schemas against the Foxglove SDK's own definitions of the
same messages: the SDK (``foxglove-sdk``) carries each as a protobuf FileDescriptorSet
(``foxglove.messages.Log.get_schema()``), which is read here field by field. Every field
the SDK defines is in btcap's schema under the same name, with the JSON type Foxglove's
JSON encoding gives it (numbers, strings, booleans, base64 bytes, ``{sec, nsec}`` times,
objects, arrays) and every enumeration with the SDK's names and numbers; and every
message a recording writes on a ``foxglove.*`` channel uses only those fields."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from btcap.monitor.foxschemas import FRAME_TRANSFORMS, GRID, LOG, SCENE_UPDATE
from btcap.monitor.mcaprecord import McapRecorder
from btcap.monitor.record import read_record

messages = pytest.importorskip("foxglove.messages")

OURS = {
    "foxglove.Log": LOG,
    "foxglove.Grid": GRID,
    "foxglove.SceneUpdate": SCENE_UPDATE,
    "foxglove.FrameTransforms": FRAME_TRANSFORMS,
}
DATA = Path(__file__).parents[2] / "sim" / "data"

# FieldDescriptorProto.Type numbers -> the JSON type Foxglove writes them as.
_DOUBLE, _FLOAT, _BOOL, _STRING, _MESSAGE, _BYTES, _ENUM = 1, 2, 8, 9, 11, 12, 14
_INTEGERS = {3, 4, 5, 6, 7, 13, 15, 16, 17, 18}
_REPEATED = 3
_TIMES = {".google.protobuf.Timestamp": "time", ".google.protobuf.Duration": "duration"}


def _fields(data: bytes) -> list[tuple[int, int | bytes]]:
    """The (field number, value) pairs of one protobuf message: varints and
    length-delimited values (all a descriptor holds)."""
    out: list[tuple[int, int | bytes]] = []
    i = 0
    while i < len(data):
        key, i = _varint(data, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(data, i)
            out.append((number, value))
        elif wire == 2:
            size, i = _varint(data, i)
            out.append((number, data[i : i + size]))
            i += size
        else:
            raise AssertionError(f"wire type {wire} in a descriptor")
    return out


def _varint(data: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        b = data[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if not b & 0x80:
            return value, i


def _text(v: int | bytes) -> str:
    assert isinstance(v, bytes)
    return v.decode()


def _definitions(schema_data: bytes) -> tuple[dict[str, Any], dict[str, dict[str, int]]]:
    """Messages (full name -> [(field, type, label, type name)]) and enumerations (full
    name -> {value name: number}) of a FileDescriptorSet."""
    msgs: dict[str, Any] = {}
    enums: dict[str, dict[str, int]] = {}

    def enum(prefix: str, data: bytes) -> None:
        name, values = "", {}
        for n, v in _fields(data):
            if n == 1:
                name = _text(v)
            elif n == 2:
                parts = dict(_fields(v))  # type: ignore[arg-type]
                values[_text(parts[1])] = int(parts.get(2, 0))  # type: ignore[arg-type]
        enums[f"{prefix}.{name}"] = values

    def message(prefix: str, data: bytes) -> None:
        parts = _fields(data)
        name = next(_text(v) for n, v in parts if n == 1)
        full = f"{prefix}.{name}"
        found = []
        for n, v in parts:
            if n == 2:
                f = dict(_fields(v))  # type: ignore[arg-type]
                found.append((_text(f[1]), f[5], f.get(4, 1), _text(f.get(6, b""))))
            elif n == 3:
                message(full, v)  # type: ignore[arg-type]
            elif n == 4:
                enum(full, v)  # type: ignore[arg-type]
        msgs[full] = found

    for n, file in _fields(schema_data):
        assert n == 1
        parts = _fields(file)  # type: ignore[arg-type]
        package = next((_text(v) for k, v in parts if k == 2), "")
        for k, v in parts:
            if k == 4:
                message(f".{package}", v)  # type: ignore[arg-type]
            elif k == 5:
                enum(f".{package}", v)  # type: ignore[arg-type]
    return msgs, enums


def _compare(
    name: str, ours: dict[str, Any], msgs: dict[str, Any], enums: dict[str, Any], where: str
) -> None:
    props = ours.get("properties", {})
    defined = {field for field, *_ in msgs[name]}
    assert set(props) == defined, (
        f"{where} ({name}): {sorted(props)} != the SDK's {sorted(defined)}"
    )
    for field, kind, label, type_name in msgs[name]:
        mine = props[field]
        at = f"{where}.{field}"
        if label == _REPEATED:
            assert mine["type"] == "array", at
            mine = mine["items"]
        if kind == _MESSAGE and type_name in _TIMES:
            assert mine["type"] == "object", at
            assert mine["title"] == _TIMES[type_name], at
            assert set(mine["properties"]) == {"sec", "nsec"}, at
        elif kind == _MESSAGE:
            if mine["properties"]:  # a primitive btcap writes none of is left open
                _compare(type_name, mine, msgs, enums, at)
            else:
                assert mine["type"] == "object", at
        elif kind == _ENUM:
            values = {alt["title"]: alt["const"] for alt in mine["oneOf"]}
            assert values == enums[type_name], at
        elif kind in (_DOUBLE, _FLOAT):
            assert mine["type"] == "number", at
        elif kind in _INTEGERS:
            assert mine["type"] == "integer", at
        elif kind == _BOOL:
            assert mine["type"] == "boolean", at
        elif kind == _STRING:
            assert mine["type"] == "string", at
        elif kind == _BYTES:
            assert mine == {"type": "string", "contentEncoding": "base64"}, at
        else:
            raise AssertionError(f"{at}: protobuf type {kind}")


@pytest.mark.parametrize("name", sorted(OURS))
def test_each_schema_is_the_sdks_definition(name: str) -> None:
    cls = getattr(messages, name.split(".")[1])
    schema = cls.get_schema()
    assert schema.name == name
    assert schema.encoding == "protobuf"
    msgs, enums = _definitions(schema.data)
    _compare(f".{name}", OURS[name], msgs, enums, name)


def test_every_foxglove_message_a_recording_writes_uses_the_sdks_fields(tmp_path: Path) -> None:
    """A recording's world drawn (map, areas, robots, objects, poses) and its log lines:
    no field the SDK does not define, anywhere in a message."""
    from mcap.reader import make_reader

    events = _small_run(tmp_path)
    path = tmp_path / "run.mcap"
    recorder = McapRecorder(path)
    recorder.write(events)
    recorder.close()
    seen: set[str] = set()
    with path.open("rb") as f:
        for schema, _, msg in make_reader(f).iter_messages():
            if schema is None or schema.name not in OURS:
                continue
            seen.add(schema.name)
            cls = getattr(messages, schema.name.split(".")[1])
            msgs, _ = _definitions(cls.get_schema().data)
            _uses(f".{schema.name}", json.loads(msg.data), msgs, schema.name)
    assert seen == set(OURS)


def _uses(name: str, value: Any, msgs: dict[str, Any], where: str) -> None:
    fields = {field: (kind, type_name) for field, kind, _, type_name in msgs[name]}
    assert isinstance(value, dict), where
    for key, v in value.items():
        assert key in fields, f"{where}.{key}: not a field of {name[1:]}"
        kind, type_name = fields[key]
        if kind == _MESSAGE and type_name not in _TIMES:
            for item in v if isinstance(v, list) else [v]:
                _uses(type_name, item, msgs, f"{where}.{key}")


def _small_run(tmp_path: Path) -> list[dict[str, Any]]:
    """The events of a --fast run of tests/sim/data/small.yaml recorded as JSON Lines."""
    from btcap.cli import main

    out = tmp_path / "jsonl"
    args = ["run", str(DATA / "small.yaml"), "--fast", "--quiet", "--out", str(out)]
    assert main([*args, "--record", str(tmp_path / "run.jsonl")]) == 0
    return read_record(tmp_path / "run.jsonl")
