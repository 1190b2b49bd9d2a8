"""The robot's one body: it runs at most one execution, and may hold one more queued.

The contract for estimates (a simulated robot keeps it, a real one must): an
implementation's bid, asked again while the robot runs that very work, says what
*finishing* it would cost from here and now: the drive left from where the robot is,
then the work left, not the cost from where it started. Re-evaluation compares it with
other robots' fresh bids, so a stale estimate moves work to a robot that is in fact
further from done (and back again once the estimate is refreshed); and only an estimate
that follows the robot can rise when its path gets blocked, news the run's origin
re-evaluates on at once (:mod:`btcap.team.core.costwatch`). Read the robot's pose and
progress when asked (odometry, the action server's feedback), not the values at award.
A bid for *other* work made while busy (a queued task, or a time-extended bid,
``Bid.after``) prices that work from where the work held leaves the robot, after it.
"""

from __future__ import annotations

from collections.abc import Callable

from btcap.team.ids import ExecutionId

__all__ = ["Body"]


class Body:
    """Idle, running one execution, or (with ``queue_after_current``) running one with one
    more accepted and waiting. Local and remote executions share it: a robot that drives
    for its own tree cannot drive for another's at the same time."""

    __slots__ = (
        "_queued_cost",
        "_running_cost",
        "on_free",
        "queue_after_current",
        "queued",
        "running",
    )

    def __init__(
        self, *, queue_after_current: bool = False, on_free: Callable[[], None] | None = None
    ) -> None:
        self.queue_after_current = queue_after_current
        #: Called when the body comes free (news for work waiting for a robot).
        self.on_free = on_free
        self.running: ExecutionId | None = None
        self.queued: ExecutionId | None = None
        self._running_cost = 0.0
        self._queued_cost = 0.0

    @property
    def idle(self) -> bool:
        return self.running is None

    def holds(self, execution: ExecutionId) -> bool:
        return execution == self.running or execution == self.queued

    def wait_cost(self) -> float | None:
        """What a new task waits behind: 0 when idle, the current bid when it could be
        queued, None when the body can take no more (a busy robot does not bid)."""
        if self.running is None:
            return 0.0
        if self.queue_after_current and self.queued is None:
            return self._running_cost
        return None

    def committed_cost(self) -> float:
        """What the body must finish before it could start anything new: the running
        work's latest estimate and the queued one's cost (a time-extended bid's wait)."""
        if self.running is None:
            return 0.0
        return self._running_cost + (self._queued_cost if self.queued is not None else 0.0)

    def estimate(self, execution: ExecutionId, cost: float) -> None:
        """A fresh estimate of what finishing ``execution`` costs (see the module's
        contract): if it runs, a task queued behind it waits that long, not as long as it
        would have taken when it was awarded. (A queued one's estimate is priced from
        where the robot is now, not where it will be: it is not taken.)"""
        if execution == self.running:
            self._running_cost = cost

    def busy_reason(self) -> str | None:
        """Why an award must be declined now, or None if the body can take it."""
        if self.wait_cost() is None:
            return f"busy with {self.running}"
        return None

    def take(self, execution: ExecutionId, cost: float) -> bool:
        """Reserve the body for ``execution``; True if it runs now, False if it is queued.

        The caller checked :meth:`busy_reason` first.
        """
        if self.running is None:
            self.running, self._running_cost = execution, cost
            return True
        if self.queue_after_current and self.queued is None:
            self.queued, self._queued_cost = execution, cost
            return False
        raise RuntimeError(f"body busy with {self.running} and {self.queued}")

    def reserve_exchange(
        self, execution: ExecutionId, cost: float, handing: ExecutionId
    ) -> str | None:
        """Hold ``execution`` paused beside the running ``handing``, which this robot hands
        over in an exchange (:mod:`btcap.team.core.exchange`); why not, or None. It waits
        in the queue's place: when ``handing`` is released it runs, and releasing it first
        (the exchange aborted) leaves the body as it was."""
        if handing != self.running:
            return f"not running {handing} (running {self.running})"
        if self.queued is not None:
            return f"busy with {self.running} and {self.queued}"
        self.queued, self._queued_cost = execution, cost
        return None

    def release(self, execution: ExecutionId) -> ExecutionId | None:
        """``execution`` ended or was dropped; returns the queued one that now runs, if any."""
        if execution == self.queued:
            self.queued = None
            return None
        if execution != self.running:
            return None
        self.running, self.queued = self.queued, None
        self._running_cost = self._queued_cost
        if self.running is None and self.on_free is not None:
            self.on_free()
        return self.running
