"""Whether a ROS server counts as there, from a series of checks of it.

A check can fail while the server is fine: on a loaded machine a ROS 1 service probe (a
master lookup, then a connection) may time out once. Were one failed check enough, the
robot would stop bidding for a moment (an ``UnassignableWarning`` if it was the only
one). So a server once seen counts as gone only after ``fails`` checks in a row failed
*and* ``window_s`` passed since its last success (both: a burst of quick failures and one
failure after a stalled poller alike stay short of it); it counts as back at the first
success. A server never seen counts as not there.

Sans-IO: the caller checks and says when, on a clock of its own.
"""

from __future__ import annotations

__all__ = ["FAILS", "WINDOW_S", "Availability"]

#: Failed checks in a row before a server seen counts as gone ...
FAILS = 3
#: ... and seconds since its last success, at least.
WINDOW_S = 1.0


class Availability:
    """One server's availability, updated by :meth:`check`."""

    __slots__ = ("_failed", "_last_ok", "fails", "ready", "window_s")

    def __init__(self, fails: int = FAILS, window_s: float = WINDOW_S) -> None:
        if fails < 1 or window_s < 0:
            raise ValueError(f"Availability: fails >= 1 and window_s >= 0, not {fails}, {window_s}")
        self.fails = fails
        self.window_s = window_s
        self.ready = False
        self._failed = 0
        self._last_ok = 0.0

    def check(self, ok: bool, t: float) -> bool:
        """Count a check made at ``t`` (seconds) that found the server (``ok``) or not; the
        availability after it."""
        if ok:
            self.ready = True
            self._failed = 0
            self._last_ok = t
        elif self.ready:
            self._failed += 1
            if self._failed >= self.fails and t - self._last_ok >= self.window_s:
                self.ready = False
                self._failed = 0
        return self.ready
