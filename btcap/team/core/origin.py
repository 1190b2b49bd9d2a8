"""The origin's lease table: executions its capability nodes run on other robots.

Every remote execution holds a lease that any word from its executor renews (a status,
or a keep-alive while no tick traffic flows). A lapsed lease, the executor leaving the
team, or the executor saying it no longer has the run makes the execution *lost*: the
capability node then re-assigns the work with its latest inputs. Only an execution's
executor may report on it; a report on an execution this robot gave up on is answered
with a cancel, so a robot declared dead that comes back stops its stale run. (A report
that overtakes the award's acceptance is simply early, and ignored.)

Every renewal echoes the newest stamp the executor sent about its run, and a run given up
on before its lease surely ended (its robot declared failed, the run moved or cancelled)
fences its task until then (:mod:`btcap.team.core.fence`): the task's next run is held.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from btcap.team.core.auction import bounded
from btcap.team.core.effects import Effect, Lost, Refused, Send
from btcap.team.core.fence import Fences
from btcap.team.ids import ExecutionId
from btcap.team.messages import RUN_DONE, CancelExecution, ExecutionStatus, KeepAlive, RunState

__all__ = ["ENDED_KEPT", "OriginLeases", "Tracked", "merge_keepalives"]

_DONE_OR_LOST = RUN_DONE | {RunState.LOST}

#: Executions given up on that are remembered, to stop their runs if they report again.
ENDED_KEPT = 1024


@dataclass(slots=True)
class Tracked:
    """What the origin knows of one remote execution (read by its capability node)."""

    execution: ExecutionId
    executor: str
    lease_s: float
    last_heard: float
    state: RunState = RunState.ASSIGNED
    outputs: dict[str, Any] = field(default_factory=dict)
    seq: int = 0  # the latest inputs sent
    acked: int = 0  # the latest inputs the executor confirmed
    detail: str = ""
    lost: bool = False
    #: The executor's newest stamp heard (its clock), echoed in every renewal.
    stamp: float | None = None
    #: When (this robot's clock) :attr:`stamp` arrived.
    stamp_at: float = -math.inf
    #: The run may have acted: awarded to start, or sent inputs (a paused one is not).
    live: bool = True

    def heard(self, stamp: float | None, now: float) -> None:
        """Word from the executor, stamped ``stamp``, arrived at ``now``."""
        self.last_heard = max(self.last_heard, now)
        if (
            stamp is not None
            and math.isfinite(stamp)
            and (self.stamp is None or stamp > self.stamp)
        ):
            self.stamp = stamp
            self.stamp_at = now

    @property
    def fenced_until(self) -> float:
        """From when on (this robot's clock) the run surely acts no more without renewals:
        ``lease_s`` after the newest stamp we echo arrived (the stamp is older than that;
        words without a newer stamp renew nothing there). Without a stamp the run never
        started; counted from ``last_heard`` all the same."""
        if self.stamp is None:
            return self.last_heard + self.lease_s
        return self.stamp_at + self.lease_s


class OriginLeases:
    """Leases of the remote executions one robot started, decided on explicit time."""

    def __init__(self, robot: str) -> None:
        self.robot = robot
        self.tracked: dict[ExecutionId, Tracked] = {}
        self._ended: OrderedDict[ExecutionId, None] = OrderedDict()
        #: Runs given up on that may still act, per task: its next run waits for them.
        self.fences = Fences()

    def track(
        self,
        execution: ExecutionId,
        executor: str,
        lease_s: float,
        now: float,
        *,
        stamp: float | None = None,
        paused: bool = False,
    ) -> Tracked:
        """The award was accepted (its reply stamped ``stamp``): the lease starts now."""
        t = Tracked(execution, executor, lease_s, now, live=not paused)
        t.heard(stamp, now)
        self.tracked[execution] = t
        return t

    def forget(self, execution: ExecutionId, now: float = -math.inf) -> None:
        """The node let the execution go (finished, cancelled, moved): a run that may
        still act fences its task until its lease surely ended or it confirms it stopped."""
        t = self.tracked.pop(execution, None)
        if t is not None:
            self._end(execution)
            if t.live and t.state not in RUN_DONE:
                self.fences.hold(execution, t.executor, t.fenced_until, now)

    def fenced(self, task: str, now: float) -> float | None:
        """Until when a new run of ``task`` (a node's path) must wait, or None."""
        return self.fences.until(task, now)

    def abandon(self, execution: ExecutionId) -> None:
        """Nobody took the execution (its awards declined or withdrawn unanswered): a
        robot that got a withdrawn award late and reports on it is told to stop."""
        self._end(execution)

    def status(
        self,
        sender: str,
        msg: ExecutionStatus,
        now: float,
        convert: Callable[[Tracked, dict[str, Any]], dict[str, Any] | str] = lambda t, v: v,
    ) -> list[Effect]:
        """A report from ``sender``; ``convert`` types its outputs or says what is wrong
        (a report with wrong outputs changes nothing, not even the lease)."""
        t = self.tracked.get(msg.execution)
        if t is None:
            if msg.execution.origin != self.robot:
                return [Refused(sender, msg, f"status of {msg.execution}, not ours")]
            if msg.state in _DONE_OR_LOST:  # a run given up on confirms it stopped
                self.fences.stopped(msg.execution, sender)
            if (
                msg.execution not in self._ended
                or msg.state in RUN_DONE
                or msg.state is RunState.LOST
            ):
                return []  # early (before the accept), a duplicate result, or a goodbye
            # A run we gave up on (its executor was declared dead, or we moved it) goes on:
            # tell it to stop now rather than at the end of its lease.
            return [Send(sender, CancelExecution(msg.execution, "no longer assigned to you"))]
        if sender != t.executor:
            # An award withdrawn unanswered that reached ``sender`` late runs there beside
            # the one its next bidder took: stop it now, not when its lease lapses (found
            # by ``btcap sim-test --heavy``, seed 15).
            stop = CancelExecution(msg.execution, f"assigned to {t.executor}")
            refused = Refused(sender, msg, f"status of {msg.execution}, run by {t.executor}")
            return [refused] if msg.state in _DONE_OR_LOST else [refused, Send(sender, stop)]
        if msg.state is RunState.LOST:  # stopped there: nothing to wait for
            # The executor's words go into a log line and a message back: cut to size.
            why = f"executor no longer has it ({bounded(msg.detail)})"
            return self._lose(t, why, now, stopped=True)
        outputs = convert(t, msg.outputs)
        if isinstance(outputs, str):
            return [Refused(sender, msg, outputs)]
        t.heard(msg.stamp, now)
        t.state = msg.state
        t.outputs = outputs
        t.acked = max(t.acked, msg.seq)
        t.detail = bounded(msg.detail)
        if msg.state in RUN_DONE:  # the result is taken once; duplicates are ignored
            del self.tracked[t.execution]
            self._end(t.execution)
        return []

    def keepalive(
        self,
        sender: str,
        executions: list[ExecutionId],
        now: float,
        stamps: Sequence[float] = (),
    ) -> None:
        for i, execution in enumerate(executions):
            t = self.tracked.get(execution)
            if t is not None and t.executor == sender:
                t.heard(stamps[i] if i < len(stamps) else None, now)

    def member_gone(
        self, robot: str, why: str, now: float = -math.inf, *, stopped: bool = False
    ) -> list[Effect]:
        """``robot`` failed or left: its runs are lost, and their tasks fenced until their
        leases surely ended (a robot declared failed may be alive, cut off) — unless it
        ``stopped`` them (its goodbye comes after its runs were stopped)."""
        out: list[Effect] = []
        for t in [t for t in self.tracked.values() if t.executor == robot]:
            out += self._lose(t, why, now, stopped=stopped)
        return out

    def expire(self, now: float) -> list[Effect]:
        out: list[Effect] = []
        for t in [t for t in self.tracked.values() if now - t.last_heard > t.lease_s]:
            out += self._lose(t, "lease lapsed", now)
        self.fences.expire(now)
        return out

    def keepalives(self) -> list[Send]:
        """One keep-alive per executor, naming every execution it runs for us whose
        executor's stamp we heard, each with that stamp (the echo renews it)."""
        by_robot: dict[str, tuple[list[ExecutionId], list[float]]] = {}
        for t in self.tracked.values():
            if t.stamp is not None:
                ids, stamps = by_robot.setdefault(t.executor, ([], []))
                ids.append(t.execution)
                stamps.append(t.stamp)
        return [
            Send(r, KeepAlive(self.robot, ids, stamps))
            for r, (ids, stamps) in sorted(by_robot.items())
        ]

    def _lose(self, t: Tracked, why: str, now: float, *, stopped: bool = False) -> list[Effect]:
        del self.tracked[t.execution]
        self._end(t.execution)
        t.lost = True
        if t.live and not stopped:
            self.fences.hold(t.execution, t.executor, t.fenced_until, now)
        # Best effort: if only its reports were lost, the old run must not go on beside
        # the one the node starts next.
        stop = Send(t.executor, CancelExecution(t.execution, f"re-assigned: {why}"))
        return [Lost(t.execution, t.executor, why), stop]

    def _end(self, execution: ExecutionId) -> None:
        self._ended[execution] = None
        while len(self._ended) > ENDED_KEPT:
            self._ended.popitem(last=False)


def merge_keepalives(robot: str, *groups: list[Send]) -> list[Send]:
    """One keep-alive per peer, for the executions of both sides shared with it (each
    with its stamp: the two sides' messages carry one for every execution, or none)."""
    ids: dict[str, tuple[list[ExecutionId], list[float]]] = {}
    for group in groups:
        for send in group:
            msg = send.message
            executions, stamps = ids.setdefault(send.to, ([], []))
            if len(msg.stamps) != len(msg.executions):  # unstamped: none is renewed
                stamps.extend([math.nan] * len(msg.executions))
            else:
                stamps.extend(msg.stamps)
            executions.extend(msg.executions)
    return [Send(peer, KeepAlive(robot, e, s)) for peer, (e, s) in ids.items()]
