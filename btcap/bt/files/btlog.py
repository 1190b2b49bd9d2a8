"""Tree logs Groot2 replays: BehaviorTree.CPP 4's ``.btlog`` (its FileLogger2 format).

The file is ``BTCPP4-FileLogger2``, a protocol byte (1), the length of the XML as a
little-endian int32, the XML of the tree (:func:`~btcap.bt.files.btcpp_write.btcpp_xml`),
the first timestamp as an int64 of microseconds since the epoch, then one 9-byte record
per status change: 6 bytes of microseconds since the first timestamp, the node's uid
(uint16) and its BehaviorTree.CPP status (a byte: 0 IDLE, 1 RUNNING, 2 SUCCESS,
3 FAILURE, 4 SKIPPED), all little-endian.

:class:`BtlogRecorder` follows a btcap tree's ticks (while it is attached, each node of
the tree is switched to a subclass of its own class whose ``tick`` reports to the
recorder; closing switches them back, and other trees pay nothing) through
:class:`~btcap.bt.files.btcpp_status.StatusFollower` and writes the changes
BehaviorTree.CPP's logger would, with times from the tree's clock (virtual time in a
``--fast`` run). It writes the file as it goes, at least every ``flush_s`` seconds of
wall time, so a run that is killed leaves a file readable up to its last write.
"""

from __future__ import annotations

import dataclasses
import struct
import time
from pathlib import Path
from types import TracebackType

from btcap.bt.files.btcpp_status import StatusFollower
from btcap.bt.files.btcpp_write import btcpp_xml, numbered
from btcap.bt.node import Node
from btcap.bt.state import State, TreeError
from btcap.bt.tree import Subtree, Tree

__all__ = ["HEADER", "Btlog", "BtlogError", "BtlogRecorder", "read_btlog"]

#: What a BehaviorTree.CPP 4 ``.btlog`` starts with: the format's name and protocol 1.
HEADER = b"BTCPP4-FileLogger2\x01"
_RECORD = 9
_MAX_UID = 0xFFFF


class BtlogError(TreeError):
    """A file is not a ``.btlog`` this module can read, or a tree cannot be logged in one."""


@dataclasses.dataclass(frozen=True)
class Btlog:
    """A ``.btlog`` read back: the tree's XML, the first timestamp (µs since the epoch) and
    the transitions ``(µs since the first timestamp, uid, status)``; ``partial`` when the
    file ends inside a record (a run that was killed)."""

    xml: str
    first_us: int
    transitions: list[tuple[int, int, int]]
    partial: bool = False


def read_btlog(path: str | Path) -> Btlog:
    """Read a ``.btlog`` (btcap's or BehaviorTree.CPP's); raises BtlogError naming the file
    and what was expected."""
    data = Path(path).read_bytes()
    if not data.startswith(HEADER):
        raise BtlogError(f"{path}: expected a .btlog starting with {HEADER!r}")
    at = len(HEADER)
    if len(data) < at + 4:
        raise BtlogError(f"{path}: ends before the length of the tree's XML")
    (size,) = struct.unpack_from("<i", data, at)
    at += 4
    if size < 0 or len(data) < at + size + 8:
        raise BtlogError(f"{path}: ends inside the tree's XML ({size} bytes announced)")
    xml = data[at : at + size].decode()
    (first,) = struct.unpack_from("<q", data, at + size)
    at += size + 8
    body = memoryview(data)[at:]
    whole = len(body) - len(body) % _RECORD
    out = [
        (int.from_bytes(body[i : i + 6], "little"), body[i + 6] | body[i + 7] << 8, body[i + 8])
        for i in range(0, whole, _RECORD)
    ]
    return Btlog(xml, first, out, partial=whole != len(body))


class BtlogRecorder:
    """Write ``tree``'s run to ``path`` (a ``.btlog``) while it ticks, until :meth:`close`.

    Attach before the first tick; a usable context manager. ``tree.untick()`` and
    ``tree.reset()`` are logged as BehaviorTree.CPP's ``haltTree``. The tree's shape is
    the one it had when the recorder was made (the XML is written then): nodes added
    later are not logged. One recorder per tree at a time.
    """

    def __init__(self, tree: Tree, path: str | Path, *, flush_s: float = 0.01) -> None:
        path = Path(path)
        if path.suffix != ".btlog":
            raise BtlogError(f"{path}: a tree log for Groot2 must be named *.btlog")
        nodes = numbered(tree)
        if len(nodes) > _MAX_UID:
            raise BtlogError(f"tree {tree.name!r}: {len(nodes)} nodes, a .btlog holds {_MAX_UID}")
        xml = btcpp_xml(tree, nodes).encode()
        self.tree = tree
        self.path = path
        self._flushed = 0
        self._flush_s = flush_s
        self._buf = bytearray()
        self._file = path.open("wb")
        self._file.write(HEADER + struct.pack("<i", len(xml)) + xml)
        self._file.write(struct.pack("<q", time.time_ns() // 1000))
        self._file.flush()
        self._last_flush = time.monotonic()
        self._clock = tree.clock
        self._t0 = self._clock.now()
        self._stamp = bytes(6)
        #: The uid and status bytes of a record, by ``uid * 5 + status``.
        self._tails = [
            bytes((k // 5 & 0xFF, k // 5 >> 8, k % 5)) for k in range(5 * len(nodes) + 5)
        ]
        self._follower = StatusFollower(nodes)
        self._classes = [(n, type(n)) for _, n, _ in nodes]
        logged = _logged_classes({cls for _, cls in self._classes}, self._follower)
        for node, cls in self._classes:
            node.__class__ = logged[cls]
        self._tick, self._untick, self._reset = tree.tick, tree.untick, tree.reset
        # Instance attributes: Tree.run, tick_once and the CLI call ``tree.tick()``.
        tree.tick = self._ticked  # type: ignore[method-assign]
        tree.untick = self._halted  # type: ignore[method-assign]
        tree.reset = self._reset_all  # type: ignore[method-assign]

    @property
    def transitions(self) -> int:
        """Status changes logged so far."""
        return (self._flushed + len(self._buf)) // _RECORD

    def _stamp_now(self) -> None:
        """The time of the changes to come: the tree's clock as a tick or halt starts."""
        us = int((self._clock.now() - self._t0) * 1_000_000)
        self._stamp = (us & 0xFFFFFFFFFFFF).to_bytes(6, "little")

    def _take(self) -> None:
        """Move the follower's changes into the buffer as records, stamped now."""
        changes = self._follower.changes
        n = len(changes)
        if n:
            # Column by column, each at C speed: the stamp's 6 bytes, then uid and status.
            tails = b"".join(map(self._tails.__getitem__, changes))
            records = bytearray(_RECORD * n)
            stamp = self._stamp
            for j in range(6):
                records[j::_RECORD] = stamp[j : j + 1] * n
            for j in range(3):
                records[6 + j :: _RECORD] = tails[j::3]
            self._buf += records
            changes.clear()

    def _ticked(self) -> State:
        self._stamp_now()
        try:
            state = self._tick()
        except BaseException:
            self._take()
            raise
        self._follower.root_done(1, state)
        self._take()
        self._maybe_flush()
        return state

    def _halted(self) -> None:
        self._stamp_now()
        self._untick()
        self._follower.halt_tree(1)
        self._take()
        self._maybe_flush()

    def _reset_all(self) -> None:
        self._stamp_now()
        self._reset()
        self._follower.halt_tree(1)
        self._take()
        self._maybe_flush()

    def _maybe_flush(self) -> None:
        if self._buf and time.monotonic() - self._last_flush >= self._flush_s:
            self.flush()

    def flush(self) -> None:
        """Write what was logged so far to the file."""
        if self._file.closed:
            return
        self._file.write(self._buf)
        self._file.flush()
        self._flushed += len(self._buf)
        self._buf.clear()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Write the rest, close the file and stop following the tree."""
        if self._file.closed:
            return
        self.flush()
        self._file.close()
        for name in ("tick", "untick", "reset"):
            self.tree.__dict__.pop(name, None)
        for node, cls in self._classes:
            node.__class__ = cls

    def __enter__(self) -> BtlogRecorder:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def _logged_classes(
    classes: set[type[Node]], follower: StatusFollower
) -> dict[type[Node], type[Node]]:
    """For each node class, a subclass whose ``tick`` tells ``follower`` (same name, no new
    slots, so a node can be switched to it and back while the recorder is attached)."""
    out: dict[type[Node], type[Node]] = {}
    for cls in classes:
        leaf = cls.MAX_CHILDREN == 0 and not issubclass(cls, Subtree)
        space = {"__slots__": (), "tick": follower.wrap(cls.tick, leaf)}
        space.update(__module__=cls.__module__, __qualname__=cls.__qualname__)
        out[cls] = type(cls.__name__, (cls,), space)
    return out
