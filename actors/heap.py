"""Giving freed memory back to the system after a burst of hostile input (glibc only).

glibc keeps the heap a burst of big messages freed for reuse, so a robot that survived
a flood of made-up members stayed 50-100 MB bigger after each (measured by
``python -m btcap.bench attacks``: 42 -> 92 -> 132 MB over two floods of 200, 46-48 MB
with a trim after each). :class:`HeapTrim` calls ``malloc_trim`` once such a burst is
over: in a worker thread (ctypes lets go of the GIL; the loop went on within 10 ms in
that bench), at most once per ``every_s``. Elsewhere (musl, macOS, Windows) it does
nothing.
"""

from __future__ import annotations

import asyncio
import ctypes
import ctypes.util
import sys
import time
from collections.abc import Callable

__all__ = ["HeapTrim", "malloc_trim"]


def _find_trim() -> Callable[[int], int] | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim: Callable[[int], int] = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc
        return None
    return trim


_TRIM = _find_trim()


def malloc_trim() -> bool:
    """Return the free heap to the system now (blocking: call it off the loop); whether
    there was anything to call."""
    if _TRIM is None:
        return False
    _TRIM(0)
    return True


class HeapTrim:
    """Trim once a burst is over: :meth:`burst` at each sign of one; the trim runs
    ``quiet_s`` after the last, no sooner than ``every_s`` after the one before."""

    __slots__ = ("_handle", "_last", "every_s", "quiet_s", "trims")

    def __init__(self, quiet_s: float = 1.0, every_s: float = 10.0) -> None:
        self.quiet_s = quiet_s
        self.every_s = every_s
        self.trims = 0  #: trims run
        self._handle: asyncio.TimerHandle | None = None
        self._last = -float("inf")

    def burst(self) -> None:
        """Something big was just let go (members forgotten, a flood refused)."""
        if _TRIM is None:
            return
        loop = asyncio.get_running_loop()
        if self._handle is not None:
            self._handle.cancel()
        at = max(time.monotonic() + self.quiet_s, self._last + self.every_s)
        self._handle = loop.call_later(at - time.monotonic(), self._trim, loop)

    def _trim(self, loop: asyncio.AbstractEventLoop) -> None:
        self._handle = None
        self._last = time.monotonic()
        self.trims += 1
        loop.run_in_executor(None, malloc_trim)

    def cancel(self) -> None:
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
