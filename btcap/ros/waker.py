"""News from a ROS bridge's thread (rclpy's executor, ROS 1's reader) for a tree on the
event loop: the tree is ticked soon instead of at its next period, one hand-over at a time,
and feedback at most every :data:`FEEDBACK_WAKE_S`.
"""

from __future__ import annotations

import time
from typing import Any

from btcap.bt.running import nudge

__all__ = ["FEEDBACK_WAKE_S", "Waker"]

#: Feedback ticks a node's tree ahead of its period at most this often (50 Hz): enough to
#: show progress, where a server's 1 kHz stream would tick the whole tree (and a remote
#: run's origin, told after every tick) a thousand times a second.
FEEDBACK_WAKE_S = 0.02


class Waker:
    """News from the executor thread for a tree: ``waker()`` makes the event loop
    :func:`~btcap.bt.running.nudge` the tree soon (``call_soon_threadsafe``), once however
    many news come before it does; ``waker(minor=True)`` (feedback) only if the last
    hand-over was at least :data:`FEEDBACK_WAKE_S` ago."""

    __slots__ = ("_call", "last", "pending", "tree")

    def __init__(self, tree: Any, loop: Any) -> None:
        self.tree = tree
        self._call = loop.call_soon_threadsafe
        self.pending = False
        self.last = 0.0

    def __call__(self, minor: bool = False) -> None:  # any thread
        if self.pending or (minor and time.monotonic() - self.last < FEEDBACK_WAKE_S):
            return
        self.pending = True
        try:
            self._call(self._fire)
        except RuntimeError:  # the loop is closed: nobody ticks the tree any more
            self.pending = False

    def _fire(self) -> None:  # the loop's thread
        self.pending = False
        self.last = time.monotonic()
        nudge(self.tree)
