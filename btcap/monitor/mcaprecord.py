"""MCAP recordings: the monitor's events on typed JSON channels, with ``foxglove.Log``
lines, a simulation's world drawn for Foxglove's 3D panel and the run's metadata, for
Foxglove, Lichtblick and ``btcap replay`` (:func:`btcap.monitor.channels.messages`).

The log time of a message is its event's clock time (virtual in ``--fast`` runs), and
its sequence number is its place in the event stream, so a replay reads the events back
in exactly the order the JSON Lines recorder wrote them, and two runs of a deterministic
simulation write the same bytes. Chunks are zstd-compressed; the file is flushed after
every batch; a chunk is written when it holds 256 KiB or spans 60 s of the clock, so a run
that is killed leaves a file readable up to its last whole chunk.
"""

from __future__ import annotations

import contextlib
import struct
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import msgspec
import zstandard
from mcap.exceptions import InvalidMagic, McapError
from mcap.records import Channel, Message, Metadata
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

import btcap
from btcap.monitor.channels import LOG_TOPIC, messages
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

_encode = msgspec.json.Encoder()
_decode = msgspec.json.Decoder(dict[str, Any])


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
        self.failed: str | None = None
        self._file = path.open("wb")
        self._writer = Writer(self._file, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(PROFILE, f"btcap {btcap.__version__}")
        meta = {"btcap_version": btcap.__version__, **(metadata or {})}
        self._writer.add_metadata(METADATA_NAME, dict(sorted(meta.items())))
        self._channels: dict[str, int] = {}
        self._sequence = 0
        self._chunk_s = chunk_s
        self._chunk_t: float | None = None  # clock time of the open chunk's first event
        self._closed = False
        try:
            self._file.flush()
        except OSError:
            self._failed_start()
            raise

    def _channel(self, topic: str, schema: dict[str, Any]) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._writer.register_schema(
                schema["title"], "jsonschema", _encode.encode(schema)
            )
            cid = self._channels[topic] = self._writer.register_channel(topic, "json", sid)
        return cid

    def write(self, batch: Iterable[Event]) -> None:
        if self._closed:
            return
        try:
            self._add(batch)
            self._file.flush()
        except OSError as exc:
            self._failed(exc)

    def _add(self, batch: Iterable[Event]) -> None:
        # one loop over the batch, names bound once: a run writes thousands of messages
        writer, channels, sequence = self._writer, self._channels, self._sequence
        add = writer.add_message
        try:
            for ev in batch:
                t = float(ev["t"])
                if self._chunk_t is None:
                    self._chunk_t = t
                elif t >= self._chunk_t + self._chunk_s:  # by the clock: the same every run
                    writer.flush()  # type: ignore[no-untyped-call]
                    self._chunk_t = t
                ns, out = messages(ev)
                sequence += 1
                for topic, schema, data in out:
                    cid = channels.get(topic)
                    if cid is None:
                        cid = self._channel(topic, schema)
                    add(cid, ns, data, ns, sequence)
        finally:
            self._sequence = sequence

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._file.close()
        except OSError as exc:
            self._failed(exc)

    def _failed_start(self) -> None:
        """The header could not be written: the file is closed, what it buffered dropped."""
        with contextlib.suppress(OSError):
            self._file.close()  # (flushes again and fails, but closes)
        with contextlib.suppress(OSError):
            self._file.raw.close()

    def _failed(self, exc: OSError) -> None:
        """A full disk ends the recording (said once), never the monitor or the robot."""
        self._closed = True
        self.failed = exc.strerror or str(exc)
        log.error("monitor.record_failed", path=str(self.path), error=self.failed)
        with contextlib.suppress(OSError):
            self._file.close()


def read_mcap(path: Path) -> tuple[list[Event], dict[str, str]]:
    """The monitor events of an MCAP recording in their order, and its ``btcap``
    metadata. A file cut short (a killed run) is read up to its last whole chunk; a file
    that is not MCAP raises :class:`ValueError` naming what is wrong."""
    topics: dict[int, str] = {}
    found: list[tuple[int, bytes]] = []
    meta: dict[str, str] = {}
    header = False  # a whole record was read: an MCAP file, perhaps cut short
    with path.open("rb") as f:
        reader = StreamReader(f, record_size_limit=1 << 30)
        try:
            for record in reader.records:
                header = True
                if isinstance(record, Channel):
                    topics[record.id] = record.topic
                elif isinstance(record, Message):
                    if topics.get(record.channel_id, LOG_TOPIC).startswith("/btcap/"):
                        found.append((record.sequence, record.data))
                elif isinstance(record, Metadata) and record.name == METADATA_NAME:
                    meta = dict(record.metadata)
        except InvalidMagic:
            raise ValueError("not an MCAP file (no MCAP magic)") from None
        except (McapError, ValueError, struct.error, zstandard.ZstdError) as exc:
            # a record cut short (a killed run): what came before it stands, if anything
            if not header:
                raise ValueError(f"not a readable MCAP file ({exc!r})") from None
    found.sort(key=lambda m: m[0])
    events = []
    for sequence, data in found:
        try:
            events.append(_decode.decode(data))
        except msgspec.DecodeError as exc:
            raise ValueError(f"message {sequence}: not a JSON object ({exc})") from None
    return events, meta
