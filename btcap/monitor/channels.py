"""The channels of an MCAP recording: one typed JSON channel per monitor event kind, and
Foxglove's ``foxglove.Log`` for the lines a person reads (who joined, who won what, why).

Every channel is JSON-encoded with a JSON Schema (MCAP's ``json`` message encoding,
``jsonschema`` schema encoding), so Foxglove and Lichtblick show the fields by name. The
schemas keep to what their JSON Schema reader takes (a channel it cannot read is dropped
whole): one ``type`` a field, ``properties`` on every object (empty on a map, whose
entries ``additionalProperties`` describes), ``items`` of one type. A field that may be
null is typed by its other type, and ``bids``, an array of ``[robot, cost]`` pairs, is
described but not listed among the properties: that reader takes no arrays of arrays.
A simulation's ``map`` and ``world`` events are drawn as well, as Foxglove's 3D panel
reads them (:mod:`btcap.monitor.scene`); the Foxglove schemas are in
:mod:`btcap.monitor.foxschemas`. :class:`Channels` says what a recording and the live
Foxglove server both send for each event.
"""

from __future__ import annotations

from typing import Any

import msgspec

from btcap.monitor.foxschemas import LOG, time_of
from btcap.monitor.scene import OBJECT_COLORS, Scene
from btcap.monitor.view import Event

__all__ = [
    "EVENT_TOPICS",
    "LOG_SCHEMA",
    "LOG_TOPIC",
    "OTHER_TOPIC",
    "Channels",
    "event_schema",
    "log_line",
    "log_time",
    "world_message",
]

_STR = {"type": "string"}
_NUM = {"type": "number"}
_STR_OR_NULL = {"type": "string", "description": "null where there is none"}
_NAME_MAP = {"type": "object", "properties": {}, "additionalProperties": {"type": "string"}}


def _obj(title: str, desc: str, props: dict[str, Any], required: list[str]) -> dict[str, Any]:
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": desc,
        "type": "object",
        "properties": {"t": _NUM, "k": _STR, **props},
        "required": ["t", "k", *required],
    }


_NODE = {
    "type": "object",
    "properties": {
        "id": _STR,
        "name": _STR,
        "type": _STR,
        "parent": _STR_OR_NULL,
        "cap": {"type": "boolean"},
        "state": _STR,
    },
    "required": ["id", "name", "type", "parent", "cap", "state"],
}

_XY = {"type": "array", "items": _NUM, "minItems": 2, "maxItems": 2}
_OBJECT = {
    "type": "object",
    "properties": {
        "id": {"type": "integer"},
        "x": _NUM,
        "y": _NUM,
        "status": {"type": "string", "enum": list(OBJECT_COLORS)},
        "by": _STR_OR_NULL,
    },
    "required": ["id", "x", "y", "status"],
}

#: Event kind -> (topic, JSON Schema of its messages: the monitor's event as it is).
EVENT_TOPICS: dict[str, tuple[str, dict[str, Any]]] = {
    "robot": (
        "/btcap/robots",
        _obj("btcap.Robot", "A robot is part of the picture.", {"robot": _STR}, ["robot"]),
    ),
    "tree": (
        "/btcap/trees",
        _obj(
            "btcap.Tree",
            "The structure of one tree of a robot, with each node's state.",
            {"robot": _STR, "tree": _STR, "nodes": {"type": "array", "items": _NODE}},
            ["robot", "tree", "nodes"],
        ),
    ),
    "states": (
        "/btcap/states",
        _obj(
            "btcap.NodeStates",
            "The latest state of each node of a tree that changed since the last batch.",
            {"robot": _STR, "tree": _STR, "states": _NAME_MAP},
            ["robot", "tree", "states"],
        ),
    ),
    "team": (
        "/btcap/team",
        _obj(
            "btcap.TeamChange",
            "A robot joined, left or failed.",
            {"robot": _STR, "change": {"type": "string", "enum": ["joined", "left", "failed"]}},
            ["robot", "change"],
        ),
    ),
    "run": (
        "/btcap/runs",
        _obj(
            "btcap.Run",
            "An execution started (a robot runs an origin's capability) or ended.",
            {
                "phase": {"type": "string", "enum": ["start", "end"]},
                "execution": _STR,
                "robot": _STR,
                "origin": _STR,
                "node": _STR,
                "capability": _STR,
                "result": _STR,
                "why": _STR_OR_NULL,
            },
            ["phase", "execution"],
        ),
    ),
    "auction": (
        "/btcap/auctions",
        _obj(
            "btcap.Auction",
            "An auction opened (why, candidates) or closed (bids cheapest first, declines, "
            "who was passed over and why, the winner). A closed one's bids are an array "
            "of [robot, cost] pairs, cheapest first.",
            {
                "phase": {"type": "string", "enum": ["open", "close"]},
                "id": _STR,
                "execution": _STR,
                "auctioneer": _STR,
                "capability": _STR,
                "node": _STR,
                "candidates": {"type": "array", "items": _STR},
                "why": _STR,
                "declined": _NAME_MAP,
                "reasons": _NAME_MAP,
                "winner": _STR_OR_NULL,
            },
            ["phase", "id", "execution"],
        ),
    ),
    "map": (
        "/btcap/map",
        _obj(
            "btcap.Map",
            "The simulated map, once: rows top first (# wall, . free, : out of reach), a "
            "cell's side in metres, the start and decontamination area as [x, y] metres.",
            {"rows": {"type": "array", "items": _STR}, "cell_m": _NUM, "start": _XY, "decon": _XY},
            ["rows", "cell_m", "start", "decon"],
        ),
    ),
    "world": (
        "/btcap/world",
        _obj(
            "btcap.World",
            "What changed in the simulated world: the state and task of the robots whose "
            "state or task changed, the objects whose status or place changed. Where the "
            "robots are is on /tf (foxglove.FrameTransforms) only.",
            {
                "robots": {
                    "type": "object",
                    "properties": {},
                    "additionalProperties": {
                        "type": "object",
                        "properties": {"up": {"type": "boolean"}, "task": _STR},
                        "required": ["up", "task"],
                    },
                },
                "objects": {"type": "array", "items": _OBJECT},
            },
            [],
        ),
    ),
    "finished": (
        "/btcap/finished",
        _obj(
            "btcap.Finished",
            "How the run ended, with a line for a person.",
            {
                "result": {"type": "string", "enum": ["succeeded", "failed", "stopped"]},
                "summary": _STR,
            },
            ["result", "summary"],
        ),
    ),
}

#: Events of a kind this btcap does not know (a newer monitor's): kept, untyped.
OTHER_TOPIC = (
    "/btcap/other",
    _obj("btcap.Event", "A monitor event of another kind.", {}, []),
)

LOG_TOPIC = "/log"
#: ``foxglove.Log``: levels 0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal.
LOG_SCHEMA: dict[str, Any] = LOG

_INFO, _WARNING = 2, 3
#: Kinds that are neither told as a ``foxglove.Log`` line nor drawn (:meth:`Channels.messages`).
_PICTURES = frozenset({"robot", "tree", "states"})
_MAX_NS = (1 << 64) - 1
_encode = msgspec.json.Encoder()


def event_schema(kind: str) -> tuple[str, dict[str, Any]]:
    """The topic and schema an event of ``kind`` is written to."""
    return EVENT_TOPICS.get(kind, OTHER_TOPIC)


def log_line(ev: Event) -> tuple[int, str, str] | None:
    """The ``foxglove.Log`` line an event is told as: (level, name, message), or None for
    kinds that are pictures rather than news (trees, states)."""
    kind = ev["k"]
    if kind == "team":
        level = _INFO if ev["change"] == "joined" else _WARNING
        return level, ev["robot"], f"{ev['robot']} {ev['change']}"
    if kind == "run":
        if ev["phase"] == "start":
            text = f"{ev['robot']} runs {ev['capability']} for {ev['origin']} ({ev['node']})"
            return _INFO, ev["robot"], text
        why = f": {ev['why']}" if ev.get("why") else ""
        level = _INFO if ev["result"] == "succeeded" else _WARNING
        return level, ev.get("robot", ""), f"run {ev['execution']} {ev['result']}{why}"
    if kind == "auction":
        if ev["phase"] == "open":
            text = f"auction {ev['id']} for {ev['capability']} ({ev['node']}): {ev['why']}"
            return _INFO, ev["auctioneer"], text
        bids = ", ".join(f"{r} {c:.1f}" for r, c in ev["bids"]) or "none"
        won = ev["winner"]
        text = f"auction {ev['id']} closed: {'won by ' + won if won else 'nobody took it'}"
        # Nobody won: the line is the auctioneer's (a recording made before close events
        # named it has no name to give).
        name = won or ev.get("auctioneer", "")
        return (_INFO if won else _WARNING), name, f"{text} (bids: {bids})"
    if kind == "finished":
        level = _INFO if ev["result"] == "succeeded" else _WARNING
        return level, "btcap", f"{ev['result']}: {ev['summary']}"
    return None


class Channels:
    """What a stream of monitor events is sent as, event by event (:meth:`messages`):
    a recording and the live Foxglove server each keep one, since a world event holds
    only what changed and its drawing is the whole picture so far (:class:`Scene`)."""

    def __init__(self) -> None:
        self.scene = Scene()

    def messages(self, ev: Event) -> tuple[int, list[tuple[str, dict[str, Any], bytes]]]:
        """What one event is sent as, at its clock time in nanoseconds: its typed
        channel, its ``foxglove.Log`` line if it has one, and its drawing if it is of
        the world (``(topic, schema, JSON)`` each). A world event's poses go on ``/tf``
        alone (:func:`world_message` says what its typed channel holds)."""
        ns = log_time(ev["t"])
        kind = ev["k"]
        if kind in _PICTURES:  # most events (a tree's states): no line, no drawing
            return ns, [(*EVENT_TOPICS[kind], _encode.encode(ev))]
        if kind == "world":
            data = world_message(ev, ns)
            out = [] if data is None else [(*EVENT_TOPICS["world"], data)]
            return ns, out + self.scene.draw(ev, ns)
        topic, schema = EVENT_TOPICS.get(kind, OTHER_TOPIC)
        out = [(topic, schema, _encode.encode(ev))]
        line = log_line(ev)
        if line is not None:
            level, name, text = line
            msg = {"timestamp": time_of(ns), "level": level, "message": text, "name": name,
                   "file": "", "line": 0}  # fmt: skip
            out.append((LOG_TOPIC, LOG_SCHEMA, _encode.encode(msg)))
        if kind == "map":
            out += self.scene.draw(ev, ns)
        return ns, out


def log_time(t: float) -> int:
    """An event's clock time as an MCAP log time: nanoseconds, an unsigned 64-bit number.
    A time outside it (a negative one, or past the year 2554) is clamped to its end: the
    event's own ``t`` is in its JSON, which is what a replay reads back."""
    ns = float(t) * 1e9
    if not 0.0 <= ns < _MAX_NS:  # NaN too
        return _MAX_NS if ns > 0 else 0
    return round(ns)


def world_message(ev: Event, ns: int) -> bytes | None:
    """A world event on ``/btcap/world``: without its poses, which ``/tf`` holds (the
    message right after it), and none at all for an event of poses alone if its time is
    a whole number of nanoseconds (as on a virtual clock), which ``/tf`` then carries;
    :func:`btcap.monitor.mcaprecord.read_mcap` puts the event back together."""
    if "poses" not in ev:
        return _encode.encode(ev)
    t = ev["t"]
    if len(ev) == 3 and isinstance(t, float) and ns / 1e9 == t:  # t, k and poses
        return None
    return _encode.encode({k: v for k, v in ev.items() if k != "poses"})
