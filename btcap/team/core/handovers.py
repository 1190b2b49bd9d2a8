"""Hand-overs of running work that would come undone, and a hold-down against them.

Re-evaluation (:mod:`btcap.team.runtime.moving`) prices the team *now*: a move goes to a
free robot clearly cheaper than the holder, an exchange (:mod:`btcap.team.core.exchange`)
is made when the cycle's total falls by the margin. Neither sees that a robot handing its
task over frees soon: a spot handing its Identify to a husky for the husky's nearby task
finishes that in seconds, comes free, and takes its Identify back from the husky, which
drove for it for nothing (issue 33: 12-46 s later). Two rules stop that, decided on
explicit costs and time:

- :func:`comes_back`: an exchange leg is predicted to come undone when the robot handing
  its task over could finish the task it receives and then its old one (each at what it
  costs it now) for less than the robot taking it bids, less the margin: the same rule
  that would move it back once the robot is free. Such an exchange is not made.
- :class:`Handovers`: a task handed from robot A to B is not handed back to A within
  :data:`HOLD_S` seconds (a hold-down), whatever the bids say then. The shell counts
  the hand-overs it refused, and any hand-over back within that time (with the
  hold-down on, none).

Sans-IO: the shell gives the clock's ``now``.
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass

__all__ = ["HOLD_S", "Handovers", "comes_back"]

#: A task handed over is not handed back to the robot it left within this many seconds
#: (the default of ``MissionConfig.hold_down_s``); a hand-over back within it is *undone*
#: (counted whatever the hold-down).
HOLD_S = 60.0


def comes_back(received: float, held: float, taken: float, margin: float) -> bool:
    """Whether a robot that hands over a task (finishing it costs it ``held`` now) for one
    that costs it ``received`` would take its old task back once free: it could do both
    for less than the robot taking it bids (``taken``), less ``margin`` of that."""
    return received + held < taken * (1.0 - margin) - 1e-9


@dataclass(frozen=True, slots=True)
class _Handover:
    frm: str
    to: str
    at: float


class Handovers:
    """The latest hand-over of each task (a capability node: its running work moved or
    exchanged), to bar handing it back to the robot it left within ``hold_s``."""

    __slots__ = ("_last", "hold_s")

    def __init__(self, hold_s: float = HOLD_S) -> None:
        if hold_s < 0:
            raise ValueError(f"hold_s {hold_s}: expected at least 0")
        self.hold_s = hold_s
        self._last: dict[Hashable, _Handover] = {}

    def barred(self, task: Hashable, now: float) -> str | None:
        """The robot ``task`` may not go to now (the one it left less than ``hold_s``
        ago), or None."""
        last = self._last.get(task)
        if last is None or now - last.at >= self.hold_s:
            return None
        return last.frm

    def allows(self, task: Hashable, to: str, now: float) -> bool:
        """Whether ``task`` may go to ``to`` now."""
        return self.barred(task, now) != to

    def moved(self, task: Hashable, frm: str, to: str, now: float) -> bool:
        """``task`` went from ``frm`` to ``to``; True if that undid its last hand-over
        (back to the robot it left less than :data:`HOLD_S` ago, whatever ``hold_s``)."""
        last = self._last.get(task)
        undone = last is not None and last.frm == to and now - last.at < HOLD_S
        self._last[task] = _Handover(frm, to, now)
        if len(self._last) > 64:  # those past both windows bar and count nothing
            keep = max(self.hold_s, HOLD_S)
            self._last = {k: h for k, h in self._last.items() if now - h.at < keep}
        return undone
