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
  :data:`HOLD_S` seconds (a hold-down), whatever the bids say then, directly or through
  another robot (A -> B -> C -> A). The shell counts the hand-overs it refused, and any
  hand-over back within that time (with the hold-down on, none).

Sans-IO: the shell gives the clock's ``now``.
"""

from __future__ import annotations

from collections.abc import Hashable

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


class Handovers:
    """The robots each task (a capability node: its running work moved or exchanged) left
    lately, to bar handing it back to any of them within ``hold_s``: not only the last
    one (a -> b -> c -> a within the hold-down undoes the move from a as surely as
    a -> b -> a does)."""

    __slots__ = ("_left", "hold_s")

    def __init__(self, hold_s: float = HOLD_S) -> None:
        if hold_s < 0:
            raise ValueError(f"hold_s {hold_s}: expected at least 0")
        self.hold_s = hold_s
        self._left: dict[Hashable, dict[str, float]] = {}  # task -> robot it left -> when

    def barred(self, task: Hashable, now: float) -> frozenset[str]:
        """The robots ``task`` may not go to now (those it left less than ``hold_s``
        ago)."""
        left = self._left.get(task)
        if not left:
            return frozenset()
        return frozenset(r for r, at in left.items() if now - at < self.hold_s)

    def allows(self, task: Hashable, to: str, now: float) -> bool:
        """Whether ``task`` may go to ``to`` now."""
        at = self._left.get(task, {}).get(to)
        return at is None or now - at >= self.hold_s

    def moved(self, task: Hashable, frm: str, to: str, now: float) -> bool:
        """``task`` went from ``frm`` to ``to``; True if that undid a hand-over (back to a
        robot it left less than :data:`HOLD_S` ago, whatever ``hold_s``)."""
        keep = max(self.hold_s, HOLD_S)
        left = self._left.setdefault(task, {})
        at = left.get(to)
        undone = at is not None and now - at < HOLD_S
        left[frm] = now
        for robot in [r for r, t in left.items() if now - t >= keep]:
            del left[robot]  # past both windows: bars and counts nothing
        if len(self._left) > 64:
            self._left = {
                k: v for k, v in self._left.items() if any(now - t < keep for t in v.values())
            }
        return undone
