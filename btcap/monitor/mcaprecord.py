"""MCAP recordings: the monitor's events on typed JSON channels, with ``foxglove.Log``
lines, a simulation's world drawn for Foxglove's 3D panel and the run's metadata, for
Foxglove, Lichtblick and ``btcap replay`` (:class:`btcap.monitor.channels.Channels`).

Written by the Foxglove SDK's MCAP writer (Rust; ``foxglove-sdk``), which takes a
message for a third of what the ``mcap`` library's Python writer did. The log time of a
message is its event's clock time (virtual in ``--fast`` runs), the messages are in the
file in the order of the event stream, and nothing in the file comes from the wall
clock, so two runs of a deterministic simulation write the same bytes and a replay reads
the events back in the order the JSON Lines recorder wrote them. Chunks are
zstd-compressed (in the calling thread: the same bytes every time); a chunk is closed
when it holds 256 KiB or spans 60 s of the clock, and is then in the file whole (the
writer seeks back to fill in its length, which empties the writer's own buffer into the
file, opened unbuffered), so a run that is killed leaves a file readable up to its last
whole chunk.
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import foxglove
import msgspec
import zstandard
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from mcap.exceptions import EndOfFile, InvalidMagic, McapError, RecordLengthLimitExceeded
from mcap.records import Channel, DataEnd, Message, Metadata
from mcap.stream_reader import StreamReader

import btcap
from btcap.monitor.channels import EVENT_TOPICS, LOG_TOPIC, Channels
from btcap.monitor.view import Event
from btcap.transports.log import get_logger

__all__ = ["CHUNK_SIZE", "MAGIC", "METADATA_NAME", "McapRecorder", "read_mcap"]

log = get_logger(__name__)

MAGIC = b"\x89MCAP0\r\n"
#: Uncompressed bytes a chunk holds before it is written ...
CHUNK_SIZE = 256 * 1024
#: ... or clock seconds it spans: a crash loses at most this much of a slow live run.
CHUNK_S = 60.0
#: The MCAP metadata record that holds the run's settings (scenario, seed, ...).
METADATA_NAME = "btcap"
PROFILE = ""  # no ROS: JSON channels
_WORLD = EVENT_TOPICS["world"][0]

#: Errors of a record that runs past the end of the file (the SDK's writer leaves a chunk
#: it has not closed with an unknown length, which is over any limit).
_CUT = (EndOfFile, RecordLengthLimitExceeded, struct.error)
_encode = msgspec.json.Encoder()
_decode = msgspec.json.Decoder(dict[str, Any])


class _File(io.FileIO):
    """The file the SDK's writer writes to, unbuffered: each write reaches the system at
    once. The first failure (a full disk) is kept and every write after it dropped, and
    the writer is told they went well: the recorder says it once (the SDK would warn at
    every message after it)."""

    error: OSError | None = None

    def write(self, data: Any, /) -> int:
        if self.error is None:
            try:
                return super().write(data)
            except OSError as exc:
                self.error = exc
        return len(data)


class McapRecorder:
    """Appends batches of events to ``path`` (created with its folder, or replaced) as
    MCAP; ``metadata`` is written first, as the ``btcap`` metadata record."""

    def __init__(
        self,
        path: Path,
        metadata: Mapping[str, str] | None = None,
        *,
        chunk_size: int = CHUNK_SIZE,
        chunk_s: float = CHUNK_S,
    ) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.failed: str | None = None  # why the recording stopped early, once it did
        self._file = _File(path, "w")
        self._context = foxglove.Context()
        options = MCAPWriteOptions(
            compression=MCAPCompression.Zstd,
            profile=PROFILE,
            chunk_size=chunk_size,
            compression_threads=0,  # zstd in this thread: no worker, the same bytes
        )
        self._closed = self._said = False
        try:
            self._writer = foxglove.open_mcap(
                self._file, context=self._context, writer_options=options
            )
        except BaseException:
            self._file.close()
            raise
        meta = {"btcap_version": btcap.__version__, **(metadata or {})}
        self._writer.write_metadata(METADATA_NAME, dict(sorted(meta.items())))
        self._log: dict[str, Callable[[bytes, int], None]] = {}  # topic -> its channel's log
        self._messages = Channels().messages
        self._chunk_s = chunk_s
        self._chunk_t: float | None = None  # clock time of the open chunk's first event
        if self._file.error is not None:  # the header: a recording that cannot start
            error = self._file.error
            self._failed_start()
            raise error

    def _channel(self, topic: str, schema: dict[str, Any]) -> Callable[[bytes, int], None]:
        log_ = self._log.get(topic)
        if log_ is None:
            sdk_schema = foxglove.Schema(
                name=schema["title"], encoding="jsonschema", data=_encode.encode(schema)
            )
            channel = foxglove.Channel(
                topic, schema=sdk_schema, message_encoding="json", context=self._context
            )
            log_ = self._log[topic] = channel.base.log
        return log_

    def write(self, batch: Iterable[Event]) -> None:
        if self._closed:
            return
        self._add(batch)
        if self._file.error is not None:
            self._failed(self._file.error)

    def _add(self, batch: Iterable[Event]) -> None:
        # one loop over the batch, names bound once: a run writes thousands of messages
        logs, messages = self._log, self._messages
        for ev in batch:
            t = float(ev["t"])
            if self._chunk_t is None:
                self._chunk_t = t
            elif t >= self._chunk_t + self._chunk_s:  # by the clock: the same every run
                self._writer.flush()  # closes the chunk
                self._chunk_t = t
            ns, out = messages(ev)
            for topic, schema, data in out:
                log_ = logs.get(topic)
                if log_ is None:
                    log_ = self._channel(topic, schema)
                log_(data, ns)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(RuntimeError):  # a failed file: said below
            self._writer.close()
        error = self._file.error
        try:
            self._file.close()
        except OSError as exc:
            error = error or exc
        if error is not None:
            self._failed(error)

    def _failed_start(self) -> None:
        """The header could not be written: the writer and the file are closed."""
        self._closed = self._said = True
        with contextlib.suppress(RuntimeError):  # the SDK's error: the file failed
            self._writer.close()
        with contextlib.suppress(OSError):
            self._file.close()

    def _failed(self, exc: OSError) -> None:
        """A full disk ends the recording (said once), never the monitor or the robot."""
        if self._said:
            return
        self._said = self._closed = True
        self.failed = exc.strerror or str(exc)
        log.error("monitor.record_failed", path=str(self.path), error=self.failed)
        with contextlib.suppress(RuntimeError):  # the SDK's error: the file failed
            self._writer.close()
        with contextlib.suppress(OSError):
            self._file.close()


def read_mcap(path: Path) -> tuple[list[Event], dict[str, str], str | None]:
    """The monitor events of an MCAP recording in their order (the file's), its ``btcap``
    metadata, and where the file breaks off if it does (None for a whole file). A world
    event's poses are read from ``/tf`` (see :func:`btcap.monitor.channels.world_message`).
    A file cut short (a killed run) or damaged (a chunk whose CRC does not match) is read
    up to its last whole, intact chunk, and the third value says so: what comes after
    is never dropped unsaid. A file that is not MCAP raises :class:`ValueError` naming
    what is wrong."""
    topics: dict[int, str] = {}
    found: list[tuple[str, bytes, int, bool]] = []  # topic, JSON, log time, a world's own /tf
    meta: dict[str, str] = {}
    header = False  # a whole record was read: an MCAP file, perhaps cut short
    last = ("", -1)  # the topic and log time of the message before
    cut: str | None = None
    ended = False  # the data section's end was read: every message was
    with path.open("rb") as f:
        size = os.fstat(f.fileno()).st_size
        reader = StreamReader(f, record_size_limit=1 << 30, validate_crcs=True)
        try:
            for record in reader.records:
                header = True
                if isinstance(record, Channel):
                    topics[record.id] = record.topic
                elif isinstance(record, Message):
                    topic = topics.get(record.channel_id, LOG_TOPIC)
                    if topic.startswith("/btcap/") or topic == "/tf":
                        # a world event's own /tf: right after it, at its time
                        own = last == (_WORLD, record.log_time)
                        found.append((topic, record.data, record.log_time, own))
                    last = (topic, record.log_time)
                elif isinstance(record, Metadata) and record.name == METADATA_NAME:
                    meta = dict(record.metadata)
                elif isinstance(record, DataEnd):
                    ended = True
        except InvalidMagic:
            if not header:
                raise ValueError("not an MCAP file (no MCAP magic)") from None
            cut = _broken(f.tell(), size, ended, "no closing magic", cut_short=True)
        except (McapError, ValueError, struct.error, zstandard.ZstdError) as exc:
            # a record cut short (a killed run) or damaged: what came before it stands
            if not header:
                raise ValueError(f"not a readable MCAP file ({exc!r})") from None
            why = str(exc) or type(exc).__name__
            cut = _broken(f.tell(), size, ended, why, cut_short=isinstance(exc, _CUT))
    events: list[Event] = []
    for number, (topic, data, ns, own) in enumerate(found, 1):
        try:
            msg = _decode.decode(data)
            if topic != "/tf":
                events.append(msg)
                continue
            poses = {
                tf["child_frame_id"]: [tf["translation"]["x"], tf["translation"]["y"]]
                for tf in msg["transforms"]
            }
        except msgspec.DecodeError as exc:
            raise ValueError(f"message {number}: not a JSON object ({exc})") from None
        except (KeyError, TypeError) as exc:
            raise ValueError(f"message {number} on /tf: no transform ({exc!r})") from None
        if own and events and events[-1].get("k") == "world":
            events[-1]["poses"] = poses  # the world event of the message before
        else:
            events.append({"t": ns / 1e9, "k": "world", "poses": poses})
    return events, meta, cut


def _broken(at: int, size: int, ended: bool, why: str, *, cut_short: bool) -> str:
    """Where and how a file breaks off, for a person: after its messages (every one read),
    cut short (a record that runs past the end: a killed run), or damaged."""
    if ended:
        return f"its summary breaks off at byte {at} of {size} ({why}); every message was read"
    if cut_short:
        return f"cut short at byte {size}, in a record never finished (a run that was killed?)"
    return f"damaged at byte {at} of {size} ({why}): nothing after it was read"
