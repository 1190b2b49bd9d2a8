"""The simulated world as Foxglove's 3D panel draws it: the map as a ``foxglove.Grid``,
robots as ``foxglove.SceneUpdate`` entities in frames of their own placed by
``foxglove.FrameTransforms``, objects and the decontamination area as entities.

Made from two monitor events a simulation emits (see :mod:`btcap.sim.running.worldfeed`):

- ``map``, once: ``rows`` (top row first; ``#`` wall, ``.`` free, ``:`` free but out of
  reach), ``cell_m`` (a cell's side in metres), ``start`` and ``decon`` (``[x, y]``).
- ``world``, whenever something changed: ``poses`` ``{robot: [x, y]}``, ``robots``
  ``{robot: {"up": bool, "task": str}}`` and ``objects`` (``[{"id", "x", "y", "status",
  "by"}]``, ``status`` one of :data:`OBJECT_COLORS`), each present only when that part
  changed, and then with only the robots or objects that changed in it (:class:`Scene`
  adds them up: the latest ``/scene`` message of a topic is the whole picture, what
  Foxglove shows after a seek).

Positions are metres in the ``map`` frame: x along the columns, y up the rows (row 0 of
the map at the top, as in its file), the grid's corner at the origin.
"""

from __future__ import annotations

import base64
from typing import Any

import msgspec

from btcap.monitor.foxschemas import FRAME_TRANSFORMS, GRID, SCENE_UPDATE, time_of
from btcap.monitor.view import Event

__all__ = ["MAP_FRAME", "OBJECT_COLORS", "SCENE_TOPICS", "Scene", "map_messages"]

MAP_FRAME = "map"
#: Topic -> schema of the scene's channels.
SCENE_TOPICS: dict[str, dict[str, Any]] = {
    "/map": GRID,
    "/scene/areas": SCENE_UPDATE,
    "/tf": FRAME_TRANSFORMS,
    "/scene/robots": SCENE_UPDATE,
    "/scene/objects": SCENE_UPDATE,
}

_RGBA = {"#": (60, 60, 60, 255), ".": (235, 235, 235, 255), ":": (150, 150, 150, 255)}
_FIELDS = [
    {"name": name, "offset": i, "type": 1}  # uint8
    for i, name in enumerate(("red", "green", "blue", "alpha"))
]
#: An object's colour by its status (r, g, b, a).
OBJECT_COLORS = {
    "hidden": (0.6, 0.6, 0.6, 0.35),  # not found yet (the simulation knows where)
    "found": (1.0, 0.8, 0.0, 1.0),  # found, not identified
    "contaminated": (0.9, 0.1, 0.1, 1.0),  # identified as contaminated
    "clean": (0.2, 0.7, 0.2, 1.0),  # identified as not contaminated
    "carried": (0.9, 0.4, 0.0, 1.0),  # on its way to the decontamination area
    "decontaminated": (0.1, 0.4, 0.9, 1.0),
}
_UP, _DOWN = (0.2, 0.4, 1.0, 1.0), (0.5, 0.5, 0.5, 0.8)
_WHITE = {"r": 1.0, "g": 1.0, "b": 1.0, "a": 1.0}
_IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
_FOREVER = {"sec": 0, "nsec": 0}
#: Drawn sizes in metres: a robot's sphere, an object's cube, an area's square (in cells).
#: A 120 x 80 m cave fills a 3D panel a few hundred pixels wide, 3 to 4 pixels a metre,
#: so each is drawn larger than the thing is: a metre would be a dot.
ROBOT_M, OBJECT_M, AREA_CELLS = 2.5, 1.5, 4

Message = tuple[str, dict[str, Any], dict[str, Any]]
_encode = msgspec.json.Encoder()


def _color(c: tuple[float, float, float, float]) -> dict[str, float]:
    return {"r": c[0], "g": c[1], "b": c[2], "a": c[3]}


def _pose(x: float, y: float, z: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": _IDENTITY}


def _entity(frame: str, eid: str, **prims: Any) -> dict[str, Any]:
    """A ``foxglove.SceneEntity`` but its timestamp (which comes first: see :class:`Scene`)."""
    entity = {"frame_id": frame, "id": eid, "lifetime": _FOREVER}
    return {**entity, "frame_locked": frame != MAP_FRAME, **prims}


def _text(text: str, z: float, size: float = 14.0, y: float = 0.0) -> dict[str, Any]:
    return {
        "pose": _pose(0.0, y, z),
        "billboard": True,
        "font_size": size,
        "scale_invariant": True,
        "color": _WHITE,
        "text": text,
    }


def map_messages(ev: Event, ns: int) -> list[Message]:
    """The map event at ``ns`` drawn for Foxglove: ``/map`` (the grid) and
    ``/scene/areas`` (the start and the decontamination area), ``(topic, schema,
    message)`` each."""
    return _map(ev, time_of(ns))


def _pixels(rows: list[str]) -> bytes:
    """Each cell's colour as four bytes, the last row first: numpy compares every cell
    with each character at once (per cell in Python it cost some 1,000 instructions)."""
    import numpy as np  # here: only a simulation draws a map, and it has numpy loaded

    codes = np.frombuffer("".join(reversed(rows)).encode("utf-32-le"), dtype="<u4")
    pixels = np.empty((codes.size, 4), dtype=np.uint8)
    pixels[:] = _RGBA["#"]  # a character of no other colour is a wall
    for ch, rgba in _RGBA.items():
        pixels[codes == ord(ch)] = rgba
    return pixels.tobytes()


def _map(ev: Event, stamp: dict[str, int]) -> list[Message]:
    rows: list[str] = ev["rows"]
    cell = float(ev["cell_m"])
    width = len(rows[0]) if rows else 0
    grid = {
        "timestamp": stamp,
        "frame_id": MAP_FRAME,
        "pose": _pose(0.0, 0.0),
        "column_count": width,
        "cell_size": {"x": cell, "y": cell},
        "row_stride": 4 * width,
        "cell_stride": 4,
        "fields": _FIELDS,
        "data": base64.b64encode(_pixels(rows)).decode("ascii"),
    }
    areas = []
    for eid, (x, y), color, label in (
        ("decon", ev["decon"], (0.1, 0.8, 0.8, 0.5), "decontamination area"),
        ("start", ev["start"], (0.8, 0.8, 0.1, 0.4), "start"),
    ):
        cube = {
            "pose": _pose(x, y, 0.05),
            "size": {"x": AREA_CELLS * cell, "y": AREA_CELLS * cell, "z": 0.1},
            "color": _color(color),
        }
        text = {**_text(label, 0.6, 12.0), "pose": _pose(x, y, 1.0)}
        areas.append({"timestamp": stamp, **_entity(MAP_FRAME, eid, cubes=[cube], texts=[text])})
    scene = {"deletions": [], "entities": areas}
    return [("/map", GRID, grid), ("/scene/areas", SCENE_UPDATE, scene)]


class Scene:
    """The simulated world as drawn so far, from world events that hold only what changed.

    ``/tf`` carries the poses of the robots that moved (Foxglove's 3D panel reads every
    transform of a recording, so a frame is where it last was, after a seek too), but
    ``/scene/robots`` and ``/scene/objects`` carry every robot or object at each change:
    after a seek, Foxglove draws a topic's last message alone. Each entity's JSON is built
    when its robot or object changes and kept, so a message of the whole picture is a
    join of kept bytes with the time put in.
    """

    def __init__(self) -> None:
        self.robots: dict[str, dict[str, Any]] = {}  #: each robot's last ``{up, task}``
        self.objects: dict[int, dict[str, Any]] = {}  #: each object's last state
        self.poses: dict[str, list[float]] = {}  #: each robot's last ``[x, y]``
        # each entity's JSON after its timestamp (``,"frame_id":...}``), by robot or object
        self._robots: dict[str, bytes] = {}
        self._objects: dict[int, bytes] = {}
        self._frames: dict[str, bytes] = {}  # a transform's JSON from after its timestamp to x
        self._parts: dict[tuple[str, bool], tuple[bytes, bytes, bytes]] = {}  # _robot_parts

    def draw(self, ev: Event, ns: int) -> list[tuple[str, dict[str, Any], bytes]]:
        """What a ``map`` or ``world`` event at ``ns`` is drawn as, ``(topic, schema,
        JSON)`` each, after adding it to the picture; nothing for other kinds."""
        kind = ev["k"]
        if kind == "map":
            return [(t, schema, _encode.encode(m)) for t, schema, m in _map(ev, time_of(ns))]
        if kind != "world":
            return []
        out = []
        stamp = _encode.encode(time_of(ns))
        head = b'{"timestamp":' + stamp + b","  # an entity's or a transform's start
        poses: dict[str, list[float]] | None = ev.get("poses")
        if poses:
            self.poses.update(poses)
            out.append(("/tf", FRAME_TRANSFORMS, self._transforms(poses, head)))
        robots: dict[str, dict[str, Any]] | None = ev.get("robots")
        if robots:
            for robot, r in robots.items():
                self.robots[robot] = r
                self._robots[robot] = self._robot(robot, bool(r["up"]), r["task"])
            entities = b",".join([head + rest for rest in self._robots.values()])
            data = b'{"deletions":[],"entities":[' + entities + b"]}"
            out.append(("/scene/robots", SCENE_UPDATE, data))
        objects: list[dict[str, Any]] | None = ev.get("objects")
        if objects:
            for o in objects:
                self.objects[o["id"]] = o
                self._objects[o["id"]] = _rest(_object(o))
            entities = b",".join([head + rest for rest in self._objects.values()])
            # entities gone from the picture are dropped: all deleted, then these
            deletion = head + b'"type":1,"id":""}'
            data = b'{"deletions":[' + deletion + b'],"entities":[' + entities + b"]}"
            out.append(("/scene/objects", SCENE_UPDATE, data))
        return out

    def _robot(self, robot: str, up: bool, task: Any) -> bytes:
        """A robot's entity JSON after its timestamp (:func:`_robot`'s, from its parts
        kept: two strings are encoded, not the dozen objects of an entity)."""
        parts = self._parts.get((robot, up))
        if parts is None:
            parts = self._parts[robot, up] = _robot_parts(robot, up)
        a, b, c = parts
        label = f"{robot} ({'up' if up else 'down'})\n{task}"
        return a + _encode.encode(task) + b + _encode.encode(label) + c

    def transforms(self, ns: int) -> bytes:
        """``/tf`` with every robot where it last was, at ``ns`` (for a late client)."""
        return self._transforms(self.poses, b'{"timestamp":' + _encode.encode(time_of(ns)) + b",")

    def _transforms(self, poses: dict[str, list[float]], head: bytes) -> bytes:
        """``foxglove.FrameTransforms`` of ``poses``, each transform ``head`` (its
        timestamp), a robot's frames kept, then its ``x`` and ``y``: the JSON a dict of
        each encodes to, for a quarter of the instructions (poses are most messages)."""
        frames = self._frames
        parts = []
        for robot, (x, y) in poses.items():
            frame = frames.get(robot)
            if frame is None:
                name = _encode.encode(robot)
                frame = frames[robot] = _PARENT + name
            xy = _encode.encode(x) + b',"y":' + _encode.encode(y)
            parts.append(head + frame + b',"translation":{"x":' + xy + _TRANSFORM_END)
        return b'{"transforms":[' + b",".join(parts) + b"]}"


_PARENT = b'"parent_frame_id":' + _encode.encode(MAP_FRAME) + b',"child_frame_id":'
#: A transform's JSON after its translation's ``y``.
_TRANSFORM_END = b',"z":0.0},"rotation":' + _encode.encode(_IDENTITY) + b"}"


def _rest(entity: dict[str, Any]) -> bytes:
    """An entity's JSON without its opening brace, to follow its timestamp."""
    return _encode.encode(entity)[1:]


def _robot(robot: str, up: bool, task: Any, label: str) -> dict[str, Any]:
    state = "up" if up else "down"
    sphere = {
        "pose": _pose(0.0, 0.0, ROBOT_M / 2),
        "size": {"x": ROBOT_M, "y": ROBOT_M, "z": ROBOT_M},
        "color": _color(_UP if up else _DOWN),
    }
    meta = [{"key": "state", "value": state}, {"key": "task", "value": task}]
    return _entity(
        robot,
        f"robot/{robot}",
        metadata=meta,
        spheres=[sphere],
        texts=[_text(label, ROBOT_M + 0.5, y=2 * ROBOT_M)],  # north of it
    )


def _robot_parts(robot: str, up: bool) -> tuple[bytes, bytes, bytes]:
    """A robot's entity JSON (after its timestamp) around its task and its label: what
    :func:`_robot` encodes to is ``a + task + b + label + c`` (JSON each)."""
    task, label = "\x00task\x00", "\x00label\x00"  # found once each in the JSON
    a, rest = _rest(_robot(robot, up, task, label)).split(_encode.encode(task))
    b, c = rest.split(_encode.encode(label))
    return a, b, c


def _object(o: dict[str, Any]) -> dict[str, Any]:
    status, by = o["status"], o.get("by")
    if by:  # it rides on the robot's sphere
        frame, x, y, z = str(by), 0.0, 0.0, ROBOT_M + OBJECT_M / 2
    else:
        frame, x, y, z = MAP_FRAME, o["x"], o["y"], OBJECT_M / 2
    cube = {
        "pose": _pose(x, y, z),
        "size": {"x": OBJECT_M, "y": OBJECT_M, "z": OBJECT_M},
        "color": _color(OBJECT_COLORS.get(status, OBJECT_COLORS["found"])),
    }
    meta = [{"key": "status", "value": status}]
    return _entity(frame, f"object/{o['id']}", metadata=meta, cubes=[cube])
