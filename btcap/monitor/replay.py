"""Replaying a recording on the monitor's page, with play, pause, seek and speed.

The picture at any time is the recording's events up to that time folded into a
:class:`~btcap.monitor.view.TeamView`, exactly as the live monitor folded them: the end
of a replay is the live page's last state. The events are handed on as they play to
:meth:`Replay.add_sink` as well (``btcap replay --foxglove``: the Foxglove server), which
see the play forwards only: a seek shows them the events from where it lands.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from btcap.monitor.hub import Hub
from btcap.monitor.record import RecordError, read_recording
from btcap.monitor.view import Event, TeamView

__all__ = ["Replay"]


class Replay:
    """A recording as a monitor source; ``speed`` is clock seconds per wall second
    (default: the whole recording in about a minute)."""

    def __init__(self, events: list[Event], *, speed: float | None = None, title: str = "") -> None:
        if not events:
            raise ValueError("the recording holds no events")
        self.events = events
        self.title = title or "btcap replay"
        self.start = min(float(e["t"]) for e in events)
        self.end = max(float(e["t"]) for e in events)
        self.speed = speed if speed is not None else max(1.0, (self.end - self.start) / 60.0)
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"replay speed {self.speed}: expected a positive number")
        self.playing = True
        #: Where the recording breaks off, if it does (:func:`read_recording`), else None.
        self.cut: str | None = None
        self.view = TeamView()
        self.t = self.start
        self._cursor = 0
        self._hub = Hub()
        self._task: asyncio.Task[None] | None = None
        self._sinks: list[Callable[[list[Event]], None]] = []
        self._apply_until(self.start)

    @classmethod
    def open(cls, path: str | Path, **kw: Any) -> Replay:
        """A replay of the recording at ``path``; :attr:`cut` says if it breaks off."""
        events, cut = read_recording(path)
        if not events:
            raise RecordError(f"{cut or path}: the recording holds no events")
        replay = cls(events, title=kw.pop("title", Path(path).name), **kw)
        replay.cut = cut
        return replay

    def add_sink(self, sink: Callable[[list[Event]], None]) -> None:
        """Hand ``sink`` the events played so far, then each batch as it plays."""
        if self._cursor:
            sink(self.events[: self._cursor])
        self._sinks.append(sink)

    @property
    def hub(self) -> Hub:
        return self._hub

    def _apply_until(self, t: float) -> list[Event]:
        batch: list[Event] = []
        events = self.events
        while self._cursor < len(events) and float(events[self._cursor]["t"]) <= t:
            batch.append(events[self._cursor])
            self.view.apply(events[self._cursor])
            self._cursor += 1
        return batch

    def _clock(self) -> Event:
        return {"t": self.t, "k": "clock", "playing": self.playing, "speed": self.speed}

    def step(self, wall_s: float) -> list[Event]:
        """Play ``wall_s`` seconds on (nothing when paused); returns the batch sent."""
        if not self.playing:
            return []
        self.t = min(self.end, self.t + wall_s * self.speed)
        if self.t >= self.end:
            self.playing = False
        played = self._apply_until(self.t)
        batch = [*played, self._clock()]
        self.view.apply(batch[-1])
        self._hub.publish(batch)
        if played:
            for sink in self._sinks:
                sink(played)
        return batch

    def seek(self, t: float) -> None:
        """Show the picture at clock time ``t`` (clamped to the recording)."""
        t = min(self.end, max(self.start, float(t)))
        if t < self.t:
            self.view, self._cursor = TeamView(), 0
        self.t = t
        self._apply_until(t)
        self.view.apply(self._clock())
        self._hub.reset()

    def control(self, msg: dict[str, Any]) -> None:
        """What a page asks: ``{"op": "play" | "pause" | "seek" | "speed", ...}``."""
        op = msg["op"]
        if op == "play":
            if self.t >= self.end:
                self.seek(self.start)
            self.playing = True
        elif op == "pause":
            self.playing = False
        elif op == "seek":
            self.seek(float(msg["t"]))
            return
        elif op == "speed":
            speed = float(msg["speed"])
            if math.isfinite(speed) and speed > 0:
                self.speed = speed
        self._hub.publish([self._clock()])

    def snapshot(self) -> dict[str, Any]:
        info = {"start": self.start, "end": self.end, "t": self.t, "playing": self.playing,
                "speed": self.speed}  # fmt: skip
        return {**self.view.snapshot(), "mode": "replay", "title": self.title, "replay": info}

    async def play(self, batch_s: float = 0.05) -> None:
        """Play on wall time until cancelled (paused, it waits for the page)."""
        loop = asyncio.get_running_loop()
        last = loop.time()
        while True:
            await asyncio.sleep(batch_s)
            now = loop.time()
            self.step(now - last)
            last = now

    async def __aenter__(self) -> Replay:
        self._task = asyncio.get_running_loop().create_task(self.play(), name="replay")
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
