"""Recordings: a monitor's events as JSON Lines, one event a line after a header line
(which holds the run's metadata), or as MCAP for Foxglove (a path ending ``.mcap``:
:mod:`btcap.monitor.mcaprecord`).

The file is flushed after every batch, so a run that crashes leaves a recording up to
its last batch (MCAP: its last whole chunk); :func:`read_record` reads either back for a
replay or a plot.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Protocol

import msgspec

from btcap.errors import BtcapError
from btcap.monitor.shapes import check_shape
from btcap.monitor.view import Event, TeamView
from btcap.transports.log import get_logger

__all__ = [
    "FORMAT",
    "RecordError",
    "Recorder",
    "Recording",
    "open_recorder",
    "read_metadata",
    "read_record",
    "read_recording",
]

log = get_logger(__name__)

FORMAT = "btcap-monitor"
VERSION = 1

#: Fields that are names wherever an event has them (a page shows them as text).
_NAMES = ("robot", "tree", "capability", "origin", "node", "execution", "id", "auctioneer",
          "result", "summary")  # fmt: skip

_decode = msgspec.json.Decoder(dict[str, Any])
_encode = msgspec.json.Encoder()


class RecordError(BtcapError, ValueError):
    """A recording cannot be read: the message names the file and line."""


class Recording(Protocol):
    """Where a monitor's batches go: JSON Lines or MCAP."""

    path: Path
    #: Why the recording stopped before its end (a full disk), or None.
    failed: str | None

    def write(self, batch: list[Event]) -> None: ...

    def close(self) -> None: ...


def open_recorder(path: Path, metadata: Mapping[str, str] | None = None) -> Recording:
    """A recorder for ``path``: MCAP if it ends ``.mcap``, else JSON Lines. An OSError
    names the file (a full disk's says only "No space left on device")."""
    try:
        if path.suffix.lower() == ".mcap":
            from btcap.monitor.mcaprecord import McapRecorder  # mcap only when asked for

            return McapRecorder(path, metadata)
        return Recorder(path, metadata)
    except OSError as exc:
        raise OSError(exc.errno, f"cannot write the recording {path}: {exc.strerror}") from None


class Recorder:
    """Appends batches of events to ``path`` (created with its folder, or replaced);
    ``metadata`` (the run's settings) goes into the header line as ``meta``."""

    def __init__(self, path: Path, metadata: Mapping[str, str] | None = None) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.failed: str | None = None
        self._file = path.open("wb")
        head: dict[str, Any] = {"format": FORMAT, "version": VERSION}
        if metadata:
            head["meta"] = dict(metadata)
        self._file.write(_encode.encode(head) + b"\n")

    def write(self, batch: Iterable[Event]) -> None:
        if self._file.closed:
            return
        try:
            self._file.write(_encode.encode_lines(batch))  # one line each, in C
            self._file.flush()
        except OSError as exc:
            self._failed(exc)

    def close(self) -> None:
        try:
            self._file.close()
        except OSError as exc:
            self._failed(exc)

    def _failed(self, exc: OSError) -> None:
        """A full disk ends the recording (said once), never the monitor or the robot."""
        self.failed = exc.strerror or str(exc)
        log.error("monitor.record_failed", path=str(self.path), error=self.failed)
        with contextlib.suppress(OSError):
            self._file.close()


def read_record(path: str | Path) -> list[Event]:
    """The events of a recording (JSON Lines or MCAP), in order; a bad file is refused
    naming the line (JSON Lines) or the message (MCAP). A file that breaks off (a killed
    run) gives what comes before the break: :func:`read_recording` says where."""
    return read_recording(path)[0]


def read_recording(path: str | Path) -> tuple[list[Event], str | None]:
    """:func:`read_record`, and None if the file is whole, else one line naming the file,
    where it breaks off and what was read up to there: a run killed mid-write leaves its
    last line or chunk unfinished, which is skipped, never silently. A run killed between
    two writes leaves whole lines: that file is said to hold no end of the run (a monitor
    that stops records how the run ended, ``finished``, whatever ended it)."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise RecordError(f"{path}: cannot read the recording: {exc.strerror}") from None
    if head.startswith(b"\x89MCAP"):
        events, _, cut = _read_mcap(path)
    else:
        events, cut = _read_lines(path)
    if cut is None:
        if not events or any(e["k"] == "finished" for e in events):
            return events, None
        cut = "holds no end of the run (no 'finished' event: a run that was killed?)"
    upto = f", up to {max(float(e['t']) for e in events):.1f} s" if events else ""
    return events, f"{path}: {cut}; read {len(events)} events{upto}"


def read_metadata(path: str | Path) -> dict[str, str]:
    """The run's metadata a recording holds (scenario, seed, ...; empty if none)."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            first = f.readline()
    except OSError as exc:
        raise RecordError(f"{path}: cannot read the recording: {exc.strerror}") from None
    if first.startswith(b"\x89MCAP"):
        return _read_mcap(path)[1]
    try:
        meta = _decode.decode(first).get("meta", {})
    except msgspec.DecodeError:
        return {}
    return {str(k): str(v) for k, v in meta.items()} if isinstance(meta, dict) else {}


def _read_mcap(path: Path) -> tuple[list[Event], dict[str, str], str | None]:
    from btcap.monitor.mcaprecord import read_mcap

    try:
        events, meta, cut = read_mcap(path)
    except OSError as exc:
        raise RecordError(f"{path}: cannot read the recording: {exc.strerror}") from None
    except ValueError as exc:
        raise RecordError(f"{path}: {exc}") from None
    view = TeamView()
    for number, obj in enumerate(events, 1):
        _check(view, obj, f"{path}: message {number}")
    return events, meta, cut


def _read_lines(path: Path) -> tuple[list[Event], str | None]:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise RecordError(f"{path}: cannot read the recording: {exc.strerror}") from None
    lines = data.splitlines()
    whole = data.endswith(b"\n")  # the recorder ends every line: else the last was cut
    if not lines:
        raise RecordError(f"{path}: empty file, not a btcap recording")
    events: list[Event] = []
    view = TeamView()  # a replay folds every event: one it cannot fold is refused here
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            obj = _decode.decode(line)
        except msgspec.DecodeError as exc:
            if number == 1:
                raise RecordError(f"{path}:1: not a btcap recording (not JSON Lines)") from None
            if number == len(lines) and not whole:  # a run killed mid-write
                return events, f"line {number} is cut short (a run that was killed?), skipped"
            raise RecordError(f"{path}:{number}: not a JSON object ({exc})") from None
        if number == 1:
            if obj.get("format") != FORMAT:
                raise RecordError(f"{path}:1: not a btcap recording (no {FORMAT!r} header)")
            if obj.get("version") != VERSION:
                raise RecordError(f"{path}:1: recording version {obj.get('version')!r}, "
                                  f"this btcap reads version {VERSION}")  # fmt: skip
            continue
        _check(view, obj, f"{path}:{number}")
        events.append(obj)
    return events, None


def _check(view: TeamView, obj: Event, where: str) -> None:
    """Refuse an event a replay could not fold, naming ``where`` it is."""
    t = obj.get("t")
    if isinstance(t, bool) or not isinstance(t, int | float) or not isinstance(obj.get("k"), str):
        raise RecordError(f"{where}: an event needs a time 't' and a kind 'k'")
    try:
        for name in _NAMES:
            if name in obj and not isinstance(obj[name], str):
                raise TypeError(f"{name!r} is {obj[name]!r}, expected a name")
        view.apply(obj)
        check_shape(obj)  # what the MCAP channels and the Foxglove scene read
    except KeyError as exc:
        raise RecordError(f"{where}: a {obj['k']!r} event: no {exc}") from None
    except (TypeError, ValueError, AttributeError) as exc:
        raise RecordError(f"{where}: a {obj['k']!r} event: {exc}") from None
