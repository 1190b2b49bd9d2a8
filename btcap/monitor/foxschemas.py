"""JSON Schemas of the Foxglove well-known messages a recording holds: ``foxglove.Log``,
``foxglove.Grid``, ``foxglove.SceneUpdate`` and ``foxglove.FrameTransforms``.

Foxglove recognises a channel by its schema's name; its panels read the fields by the
names its published definitions give them (docs.foxglove.dev, "Message schemas"). The
Foxglove SDK (``foxglove-sdk`` 0.30) carries these definitions only as protobuf inside
its binary, not as JSON Schemas, so they are written here from the published field
tables: the same names, types and nesting. ``SceneEntity`` lists the primitive arrays
btcap fills (cubes, spheres, texts) in full and the others (arrows, cylinders, lines,
triangles, models) as arrays of objects: btcap writes none of them.

In JSON, ``bytes`` fields are base64 strings and enumerations are their numbers, each
enumeration a ``oneOf`` of numeric ``const`` values with their names as titles, as in
Foxglove's published JSON Schemas. Foxglove Studio and Lichtblick read a JSON Schema only
that far: every field a single ``type`` (or such a ``oneOf``), every object with its
``properties`` (tests/btcap/monitor/test_foxglove_subset.py checks every channel's schema).
"""

from __future__ import annotations

from typing import Any

__all__ = ["FRAME_TRANSFORMS", "GRID", "LOG", "SCENE_UPDATE", "time_of"]

_DRAFT = "https://json-schema.org/draft/2020-12/schema"
_NUM = {"type": "number"}
_STR = {"type": "string"}
_BOOL = {"type": "boolean"}
_UINT = {"type": "integer", "minimum": 0}


def _obj(title: str, desc: str, **props: Any) -> dict[str, Any]:
    return {
        "title": title,
        "description": desc,
        "type": "object",
        "properties": props,
        "required": list(props),
    }


def _root(schema: dict[str, Any]) -> dict[str, Any]:
    return {"$schema": _DRAFT, **schema}


def _array(items: dict[str, Any]) -> dict[str, Any]:
    return {"type": "array", "items": items}


def _enum(title: str, desc: str, *names: str) -> dict[str, Any]:
    """An enumeration as Foxglove writes one: its values 0, 1, ... named by ``names``."""
    alternatives = [{"title": name, "const": i} for i, name in enumerate(names)]
    return {"title": title, "description": desc, "oneOf": alternatives}


_TIME = {
    "type": "object",
    "title": "time",
    "properties": {"sec": _UINT, "nsec": {**_UINT, "maximum": 999_999_999}},
    "required": ["sec", "nsec"],
}
_DURATION = {
    "type": "object",
    "title": "duration",
    "properties": {"sec": {"type": "integer"}, "nsec": {**_UINT, "maximum": 999_999_999}},
    "required": ["sec", "nsec"],
}
_VECTOR2 = _obj("foxglove.Vector2", "A vector in 2D space", x=_NUM, y=_NUM)
_VECTOR3 = _obj("foxglove.Vector3", "A vector in 3D space", x=_NUM, y=_NUM, z=_NUM)
_QUATERNION = _obj(
    "foxglove.Quaternion", "An orientation in 3D space", x=_NUM, y=_NUM, z=_NUM, w=_NUM
)
_POSE = _obj(
    "foxglove.Pose", "A position and orientation", position=_VECTOR3, orientation=_QUATERNION
)
_COLOR = _obj(
    "foxglove.Color", "A color in RGBA format, each 0 to 1", r=_NUM, g=_NUM, b=_NUM, a=_NUM
)
_KEY_VALUE = _obj("foxglove.KeyValuePair", "A key with its value", key=_STR, value=_STR)

#: ``foxglove.Log``: levels 0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal.
LOG = _root(
    _obj(
        "foxglove.Log",
        "A log message",
        timestamp=_TIME,
        level=_enum(
            "foxglove.LogLevel",
            "Log level",
            *("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"),
        ),
        message=_STR,
        name=_STR,
        file=_STR,
        line=_UINT,
    )
)

_PACKED_FIELD = _obj(
    "foxglove.PackedElementField",
    "A field of each element of packed data",
    name=_STR,
    offset=_UINT,
    type=_enum(
        "foxglove.NumericType",
        "Numeric type",
        *("UNKNOWN", "UINT8", "INT8", "UINT16", "INT16", "UINT32", "INT32", "FLOAT32", "FLOAT64"),
    ),
)

GRID = _root(
    _obj(
        "foxglove.Grid",
        "A 2D grid of data",
        timestamp=_TIME,
        frame_id=_STR,
        pose=_POSE,  # of the grid's corner: cell (0, 0) spans [0, cell_size) from it
        column_count=_UINT,
        cell_size=_VECTOR2,
        row_stride=_UINT,
        cell_stride=_UINT,
        fields=_array(_PACKED_FIELD),
        data={"type": "string", "contentEncoding": "base64"},  # row-major, rows along +y
    )
)

_CUBE = _obj("foxglove.CubePrimitive", "A cube", pose=_POSE, size=_VECTOR3, color=_COLOR)
_SPHERE = _obj("foxglove.SpherePrimitive", "A sphere", pose=_POSE, size=_VECTOR3, color=_COLOR)
_TEXT = _obj(
    "foxglove.TextPrimitive",
    "A text label",
    pose=_POSE,
    billboard=_BOOL,  # faces the camera
    font_size=_NUM,
    scale_invariant=_BOOL,  # font_size in screen pixels
    color=_COLOR,
    text=_STR,
)
_UNUSED = _array({"type": "object", "properties": {}})
_ENTITY = {
    **_obj(
        "foxglove.SceneEntity",
        "A visual element in a 3D scene, made of primitives in one frame",
        timestamp=_TIME,
        frame_id=_STR,
        id=_STR,  # replaces an earlier entity of the same id on the same topic
        lifetime=_DURATION,  # zero: until replaced or deleted
        frame_locked=_BOOL,  # follows its frame as the frame moves
        metadata=_array(_KEY_VALUE),
        arrows=_UNUSED,
        cubes=_array(_CUBE),
        spheres=_array(_SPHERE),
        cylinders=_UNUSED,
        lines=_UNUSED,
        triangles=_UNUSED,
        texts=_array(_TEXT),
        models=_UNUSED,
    ),
    "required": ["timestamp", "frame_id", "id", "lifetime", "frame_locked"],
}
_DELETION = _obj(
    "foxglove.SceneEntityDeletion",
    "Removes entities: 0 the one of ``id``, 1 all of the topic",
    timestamp=_TIME,
    type=_enum("foxglove.SceneEntityDeletionType", "Deletion type", "MATCHING_ID", "ALL"),
    id=_STR,
)
SCENE_UPDATE = _root(
    _obj(
        "foxglove.SceneUpdate",
        "An update to the entities displayed in a 3D scene",
        deletions=_array(_DELETION),
        entities=_array(_ENTITY),
    )
)

_TRANSFORM = _obj(
    "foxglove.FrameTransform",
    "Where a child frame is in its parent frame",
    timestamp=_TIME,
    parent_frame_id=_STR,
    child_frame_id=_STR,
    translation=_VECTOR3,
    rotation=_QUATERNION,
)
FRAME_TRANSFORMS = _root(
    _obj("foxglove.FrameTransforms", "An array of frame transforms", transforms=_array(_TRANSFORM))
)


def time_of(ns: int) -> dict[str, int]:
    """A Foxglove ``time`` for ``ns`` nanoseconds of the clock (clamped at zero)."""
    sec, nsec = divmod(max(ns, 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}
