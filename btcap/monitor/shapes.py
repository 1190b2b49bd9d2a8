"""The fields each monitor event kind must have for a recording to be drawn, told and
written as MCAP (:mod:`btcap.monitor.channels`, :mod:`btcap.monitor.scene`): a recording
is checked against them as it is read, so a hand-made or damaged file is refused with
one line naming the event and the field, never by a traceback halfway through a
conversion or a replay to Foxglove. Fields a kind may carry besides these are kept."""

from __future__ import annotations

from typing import Annotated, Any, Literal

import msgspec

__all__ = ["check_shape"]

_XY = tuple[float, float]


class _Map(msgspec.Struct):
    rows: list[str]
    cell_m: Annotated[float, msgspec.Meta(gt=0)]
    start: _XY
    decon: _XY


class _Robot(msgspec.Struct):
    up: bool
    task: str


class _Object(msgspec.Struct):
    id: int
    x: float
    y: float
    status: str
    by: str | None = None


class _World(msgspec.Struct):
    poses: dict[str, _XY] = msgspec.field(default_factory=dict)
    robots: dict[str, _Robot] = msgspec.field(default_factory=dict)
    objects: list[_Object] = msgspec.field(default_factory=list)


class _RunStart(msgspec.Struct):
    phase: Literal["start"]
    robot: str
    capability: str
    origin: str
    node: str


class _RunEnd(msgspec.Struct):
    phase: Literal["end"]
    result: str
    why: str | None = None


class _AuctionOpen(msgspec.Struct):
    phase: Literal["open"]
    auctioneer: str
    capability: str
    node: str
    why: str
    candidates: list[str]


class _AuctionClose(msgspec.Struct):
    phase: Literal["close"]
    bids: list[tuple[str, float]]
    winner: str | None
    declined: dict[str, str] = msgspec.field(default_factory=dict)
    reasons: dict[str, str] = msgspec.field(default_factory=dict)


_SHAPES: dict[str, tuple[type[msgspec.Struct], type[msgspec.Struct]]] = {
    "map": (_Map, _Map),
    "world": (_World, _World),
    "run": (_RunStart, _RunEnd),  # by phase: (start, anything else)
    "auction": (_AuctionOpen, _AuctionClose),
}
_FIRST = frozenset({"start", "open"})


def check_shape(ev: dict[str, Any]) -> None:
    """Raise :class:`ValueError` saying which field of ``ev`` is missing or wrong."""
    shapes = _SHAPES.get(ev["k"])
    if shapes is None:
        return
    try:
        msgspec.convert(ev, shapes[0] if ev.get("phase") in _FIRST else shapes[1])
    except msgspec.ValidationError as exc:
        raise ValueError(str(exc)) from None
