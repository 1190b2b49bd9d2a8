"""What Foxglove Studio and Lichtblick make of an MCAP recording's schemas, read back with
the ``mcap`` library: every channel's JSON Schema stays inside the part of JSON Schema
their reader turns into message definitions (a channel it cannot read is dropped whole,
found by opening a recording in Foxglove Studio 1.48), every message path the example
layout plots resolves through those definitions, and its 3D panel looks at the cave."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import anyio
import pytest
from mcap.reader import make_reader

from btcap.monitor import Monitor
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.running.runner import run_fast

SMALL = Path(__file__).parents[2] / "sim" / "data" / "small.yaml"
LAYOUT = Path(__file__).parents[3] / "examples" / "foxglove" / "btcap.json"
_SCALARS = ("boolean", "number", "integer", "string")


def _readable(schema: dict[str, Any], where: str) -> None:
    """Fails where Foxglove's JSON Schema reader would: an object needs ``properties``;
    each field is a ``oneOf`` of numeric ``const`` values (an enumeration) or has one
    ``type``; a string is plain or base64; an array's items are one scalar or object type."""
    assert schema.get("type") == "object", f"{where}: not an object"
    props = schema.get("properties")
    assert isinstance(props, dict), f"{where}: an object without properties"
    for name, field in props.items():
        at = f"{where}.{name}"
        if "oneOf" in field:
            assert all(isinstance(alt.get("const"), int | float) for alt in field["oneOf"]), at
            continue
        kind = field.get("type")
        assert kind in (*_SCALARS, "object", "array"), f"{at}: type {kind!r}"
        if kind == "string":
            assert field.get("contentEncoding") in (None, "base64"), at
        elif kind == "object":
            _readable(field, at)
        elif kind == "array":
            items = field.get("items")
            assert isinstance(items, dict), f"{at}: array without one items schema"
            assert items.get("type") in (*_SCALARS, "object"), f"{at}[]: {items.get('type')!r}"
            if items["type"] == "string":
                assert "contentEncoding" not in items, f"{at}[]"
            elif items["type"] == "object":
                _readable(items, f"{at}[]")


def _resolves(schema: dict[str, Any], path: str, where: str) -> None:
    """A message path (``.field``, ``[index]``, ``{field==value}`` filters) names fields
    the schema lists; a map (``additionalProperties``) takes any key."""
    for token in re.findall(r"\{(\w+)[^}]*\}|\.(\w+)|\[(\d+)\]", path):
        filtered, field, index = token
        if index:
            items = schema.get("items") if schema.get("type") == "array" else None
            assert isinstance(items, dict), f"{where}: [{index}] on no array of one type"
            schema = items
            continue
        if schema.get("type") == "array":
            schema = schema["items"]
        props = schema.get("properties", {})
        name = filtered or field
        if name in props:
            if field:
                schema = props[name]
        elif field and isinstance(schema.get("additionalProperties"), dict):
            schema = schema["additionalProperties"]
        else:
            raise AssertionError(f"{where}: {name!r} is not a listed field")


def _paths(node: Any) -> Iterator[str]:
    """The message paths a layout's panels read (``value`` of a series, ``topicPath``)."""
    if isinstance(node, dict):
        for key, value in node.items():
            if key in ("value", "topicPath") and isinstance(value, str):
                yield value
            else:
                yield from _paths(value)
    elif isinstance(node, list):
        for value in node:
            yield from _paths(value)


@pytest.fixture(scope="module")
def schemas(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """Each channel's JSON Schema, as a recorded ``--fast`` run's MCAP file holds it."""
    path = tmp_path_factory.mktemp("subset") / "run.mcap"

    async def record() -> None:
        with anyio.fail_after(60):
            async with Monitor(port=None, record=path, title="small") as monitor:
                await run_fast(load_scenario(SMALL), monitor=monitor)

    anyio.run(record)
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {
        ch.topic: json.loads(summary.schemas[ch.schema_id].data) for ch in summary.channels.values()
    }


@pytest.mark.slow
def test_every_channel_schema_is_one_foxglove_reads(schemas: dict[str, dict[str, Any]]) -> None:
    assert {"/map", "/log", "/scene/robots", "/btcap/auctions", "/btcap/world"} <= set(schemas)
    for topic, schema in schemas.items():
        _readable(schema, topic)


@pytest.mark.slow
def test_the_layout_reads_fields_the_schemas_list(schemas: dict[str, dict[str, Any]]) -> None:
    paths = list(_paths(json.loads(LAYOUT.read_text())))
    assert any("/btcap/world.robots." in p for p in paths)
    for path in paths:
        topic = re.match(r"/[\w/]+", path)
        assert topic is not None
        assert topic[0] in schemas, path
        _resolves(schemas[topic[0]], path[topic.end() :], path)


def test_the_layout_looks_at_the_cave() -> None:
    """Foxglove places the camera at ``targetOffset`` in the followed frame (``target``
    is only that frame's pose): the default 120 x 80 m cave's centre."""
    text = json.dumps(json.loads(LAYOUT.read_text()))
    (camera,) = re.findall(r'"cameraState": (\{[^}]*\})', text)
    assert json.loads(camera)["targetOffset"] == [60.0, 40.0, 0.0]
