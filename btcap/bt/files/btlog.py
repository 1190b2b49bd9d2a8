"""Tree logs Groot2 replays: BehaviorTree.CPP 4's ``.btlog`` (its FileLogger2 format).

The file is ``BTCPP4-FileLogger2``, a protocol byte (1), the length of the XML as a
little-endian int32, the XML of the tree (:func:`~btcap.bt.files.btcpp_write.btcpp_xml`),
the first timestamp as an int64 of microseconds since the epoch, then one 9-byte record
per status change: 6 bytes of microseconds since the first timestamp, the node's uid
(uint16) and its BehaviorTree.CPP status (a byte: 0 IDLE, 1 RUNNING, 2 SUCCESS,
3 FAILURE, 4 SKIPPED), all little-endian.

:class:`BtlogRecorder` follows a btcap tree's ticks (a profile hook active only inside
the tree's own ``tick``, so nothing else pays for it) through
:class:`~btcap.bt.files.btcpp_status.StatusFollower` and writes the changes
BehaviorTree.CPP's logger would, with times from the tree's clock (virtual time in a
``--fast`` run). It writes the file as it goes, at least every ``flush_s`` seconds of
wall time, so a run that is killed leaves a file readable up to its last write.
"""

from __future__ import annotations

import dataclasses
import struct
import sys
import time
from pathlib import Path
from types import CodeType, FrameType, TracebackType
from typing import Any

from btcap.bt.files.btcpp_status import StatusFollower
from btcap.bt.files.btcpp_write import btcpp_xml, numbered
from btcap.bt.state import State, TreeError
from btcap.bt.tree import Tree

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
    ``tree.reset()`` are logged as BehaviorTree.CPP's ``haltTree``.
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
        self.transitions = 0
        self._flush_s = flush_s
        self._buf = bytearray()
        self._file = path.open("wb")
        self._file.write(HEADER + struct.pack("<i", len(xml)) + xml)
        self._file.write(struct.pack("<q", time.time_ns() // 1000))
        self._file.flush()
        self._last_flush = time.monotonic()
        self._clock = tree.clock
        self._t0 = self._clock.now()
        self._uids = {id(n): uid for uid, n, _ in nodes}
        self._codes: set[CodeType] = {type(n).tick.__code__ for _, n, _ in nodes}
        self._follower = StatusFollower(nodes, self._record)
        self._tick, self._untick, self._reset = tree.tick, tree.untick, tree.reset
        # Instance attributes: Tree.run, tick_once and the CLI call ``tree.tick()``.
        tree.tick = self._ticked  # type: ignore[method-assign]
        tree.untick = self._halted  # type: ignore[method-assign]
        tree.reset = self._reset_all  # type: ignore[method-assign]

    def _record(self, uid: int, status: int) -> None:
        us = int((self._clock.now() - self._t0) * 1_000_000)
        self._buf += (us & 0xFFFFFFFFFFFF).to_bytes(6, "little")
        self._buf += bytes((uid & 0xFF, uid >> 8, status))
        self.transitions += 1

    def _hook(self, frame: FrameType, event: str, arg: Any) -> None:
        if frame.f_code not in self._codes:
            return
        if event == "call":
            uid = self._uids.get(id(frame.f_locals.get("self")))
            if uid is not None:
                self._follower.enter(uid)
        elif event == "return":
            uid = self._uids.get(id(frame.f_locals.get("self")))
            if uid is not None:
                if isinstance(arg, State):
                    self._follower.leave(uid, arg)
                else:  # the tick raised: nothing changed in BehaviorTree.CPP's terms
                    self._follower.abandon()

    def _ticked(self) -> State:
        previous = sys.getprofile()
        sys.setprofile(self._hook)
        try:
            state = self._tick()
        finally:
            sys.setprofile(previous)
        self._follower.root_done(1, state)
        self._maybe_flush()
        return state

    def _halted(self) -> None:
        self._untick()
        self._follower.halt_tree(1)
        self._maybe_flush()

    def _reset_all(self) -> None:
        self._reset()
        self._follower.halt_tree(1)
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

    def __enter__(self) -> BtlogRecorder:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
