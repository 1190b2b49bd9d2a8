"""The executor's side: runs this robot hosts for other robots, their leases and its body.

An award is taken only from the origin of its execution (who is also its auctioneer),
only with a lease of at most ``max_lease_s`` and only while the body can take it (that
this robot bid for it is :class:`~btcap.team.core.bounds.BidBook`'s to say). A run acts
only while leased (:mod:`btcap.team.core.fence`): from the origin's first renewal (its
inputs or keep-alives, each echoing a stamp this robot sent about the run) until the
newest echoed stamp plus the award's ``lease_s`` times ``lease_share``, when it is
stopped whether or not the origin was heard — before the origin may start another run of
the task. Only the origin may tick, pause or cancel its run, and finished runs keep their
final status for a while, so a late input is answered with the result rather than with
"unknown".
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from btcap.team.core.auction import bounded
from btcap.team.core.body import Body
from btcap.team.core.effects import Drop, Effect, Pause, Refused, Send, Start
from btcap.team.core.fence import EXECUTOR_SHARE
from btcap.team.ids import ExecutionId
from btcap.team.messages import (
    RUN_DONE,
    Award,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    PauseExecution,
    RunState,
)

__all__ = [
    "FINISHED_KEPT",
    "HostLeases",
    "Hosted",
]

R = TypeVar("R")

#: Final statuses kept to answer late inputs; older ones are forgotten first.
FINISHED_KEPT = 256


@dataclass(slots=True)
class Hosted(Generic[R]):
    """A run this robot executes for another robot's capability node."""

    execution: ExecutionId
    run: R
    inputs: dict[str, Any]
    lease_s: float  #: how long the run lives past an echoed stamp (this robot's clock)
    taken: float  #: when the award was taken: older stamps are no renewal of this run
    until: float  #: the lease's end: it is stopped then (unstarted: dropped)
    state: RunState = RunState.ASSIGNED
    outputs: dict[str, Any] = field(default_factory=dict)
    paused: bool = False
    seq: int = 0
    started: bool = False  #: renewed at least once: it may act

    def leased(self, now: float) -> bool:
        """Whether the run may act (be ticked) at ``now``."""
        return self.started and now < self.until

    @property
    def origin(self) -> str:
        return self.execution.origin


class HostLeases(Generic[R]):
    """Hosted runs and the body they share with this robot's own runs."""

    def __init__(
        self,
        robot: str,
        body: Body,
        *,
        lease_share: float = EXECUTOR_SHARE,
        max_lease_s: float = math.inf,
    ) -> None:
        self.robot = robot
        self.body = body
        self.lease_share = lease_share
        self.max_lease_s = max_lease_s
        self.hosted: dict[ExecutionId, Hosted[R]] = {}
        self.finished: OrderedDict[ExecutionId, ExecutionStatus] = OrderedDict()

    # -- awards -----------------------------------------------------------------------
    def refuse_award(self, sender: str, award: Award) -> str | None:
        """Why ``award`` must be declined before anything is built, or None."""
        execution = award.execution
        if sender != execution.origin or award.auction.auctioneer != sender:
            return f"award of {execution} from {sender}: only its origin awards it"
        if self.body.holds(execution) or execution in self.finished:
            return f"{execution} was awarded before"
        if not math.isfinite(award.lease_s) or award.lease_s <= 0:
            return f"award of {execution}: lease_s {award.lease_s!r}, expected a positive number"
        if award.lease_s > self.max_lease_s:
            return (
                f"award of {execution}: lease_s {award.lease_s:g} is over this robot's "
                f"max_lease_s {self.max_lease_s:g}"
            )
        if award.handing is not None and award.handing in self.hosted:
            # An exchange: held paused beside the run handed over, in the queue's place.
            if self.body.running != award.handing or self.body.queued is not None:
                return f"exchange for {award.handing}: not running it alone"
            if award.handing.origin != execution.origin:
                return f"exchange for {award.handing}: another origin's run"
            return None
        return self.body.busy_reason()

    def repeated(self, sender: str, award: Award) -> bool:
        """Whether ``award`` is a copy of one this robot took and still holds (the
        network delivered it twice): it is accepted again, not declined as "awarded
        before", or the auctioneer would give the task to the next bidder while it runs
        here (found by ``btcap sim-test``, seed 859)."""
        execution = award.execution
        return execution in self.hosted and sender == execution.origin == award.auction.auctioneer

    def admit(self, award: Award, run: R, inputs: dict[str, Any], cost: float, now: float) -> bool:
        """Take a remote award (checked with :meth:`refuse_award`); True if it has the
        body now (it acts from the origin's first renewal, if that comes within its lease)."""
        lease_s = award.lease_s * self.lease_share
        self.hosted[award.execution] = Hosted(
            award.execution, run, inputs, lease_s, now, now + lease_s, paused=award.paused
        )
        if award.handing is not None and self.body.running == award.handing:
            why = self.body.reserve_exchange(award.execution, cost, award.handing)
            if why is not None:  # checked by refuse_award: cannot happen
                raise RuntimeError(why)
            return False
        return self.body.take(award.execution, cost)

    # -- the origin's messages -----------------------------------------------------------
    def inputs(
        self,
        sender: str,
        msg: ExecutionInputs,
        now: float,
        convert: Callable[[Hosted[R], dict[str, Any]], dict[str, Any] | str],
    ) -> list[Effect]:
        """New inputs (``convert`` types them, or says what is wrong); answered at once."""
        execution = msg.execution
        if sender != execution.origin:
            return [Refused(sender, msg, f"inputs for {execution}, whose origin is another")]
        h = self.hosted.get(execution)
        if h is None:
            final = self.finished.get(execution) or ExecutionStatus(
                execution, self.robot, RunState.LOST, {}, msg.seq, "unknown execution"
            )
            return [Send(sender, final)]
        inputs = convert(h, msg.inputs)
        if isinstance(inputs, str):  # changes nothing: a bad seq must not hide later inputs
            return [Refused(sender, msg, inputs)]
        if msg.echo is not None:
            self._renew(h, msg.echo)
        if msg.seq > h.seq:  # an older input overtaken by a pause must not resume the run
            h.seq, h.inputs, h.paused = msg.seq, inputs, False
        return [Send(sender, self.status(h, now))]

    def pause(self, sender: str, msg: PauseExecution) -> list[Effect]:
        h = self.hosted.get(msg.execution)
        if h is None or sender != h.origin:
            return [] if h is None else [Refused(sender, msg, "pause from another than origin")]
        h.paused = True
        if self.body.running != h.execution:
            return []  # a queued run has not started: nothing to pause
        h.state = RunState.PAUSED
        return [Pause(h.execution)]

    def cancel(self, sender: str, msg: CancelExecution) -> list[Effect]:
        execution = msg.execution
        if sender != execution.origin:
            return [Refused(sender, msg, f"cancel of {execution} from another than its origin")]
        h = self.hosted.get(execution)
        if h is None:
            return []
        why = bounded(msg.reason) or "cancelled"  # logged here, sent back in our status
        # A run that may have acted confirms it stopped: its origin need not wait out the
        # lease before the task runs elsewhere (an unstarted one never acts: no word).
        done = ExecutionStatus(execution, self.robot, RunState.LOST, {}, h.seq, why)
        return [*self.drop(execution, why), *([Send(sender, done)] if h.started else [])]

    def keepalive(self, sender: str, msg: KeepAlive, now: float) -> None:
        stamps = msg.stamps
        for i, execution in enumerate(msg.executions):
            h = self.hosted.get(execution)
            if h is not None and h.origin == sender and i < len(stamps):
                self._renew(h, stamps[i])

    def _renew(self, h: Hosted[R], echo: float) -> None:
        """The origin echoed ``echo``, a stamp of ours: the run may act until ``echo``
        plus its lease (a stamp from before the award is of another run)."""
        if echo >= h.taken and math.isfinite(echo):
            h.started = True
            h.until = max(h.until, echo + h.lease_s)

    # -- the run ----------------------------------------------------------------------
    def status(self, h: Hosted[R], now: float | None = None, detail: str = "") -> ExecutionStatus:
        """``h``'s report, stamped ``now`` (this robot's clock) for its origin to echo."""
        return ExecutionStatus(h.execution, self.robot, h.state, h.outputs, h.seq, detail, now)

    def ticked(
        self,
        execution: ExecutionId,
        state: RunState,
        outputs: dict[str, Any],
        now: float | None = None,
        detail: str = "",
    ) -> list[Effect]:
        """The slot ticked the run: report it (``detail``: why it ended in ERROR, for the
        origin's user); a finished run is kept as a final status."""
        h = self.hosted.get(execution)
        if h is None:
            return []
        h.state, h.outputs = state, outputs
        report = self.status(h, now, detail)
        out: list[Effect] = [Send(h.origin, report)]
        if state in RUN_DONE:
            self.finished[execution] = report
            while len(self.finished) > FINISHED_KEPT:
                self.finished.popitem(last=False)
            out += self.drop(execution, "finished")
        return out

    def give_up(
        self, execution: ExecutionId, why: str, state: RunState = RunState.LOST
    ) -> list[Effect]:
        """The run cannot go on here (its setup failed, its status cannot be sent): tell the
        origin, with ``state`` LOST to have it re-assigned or FAILED to end it, and drop it."""
        h = self.hosted.get(execution)
        if h is None:
            return []
        final = ExecutionStatus(execution, self.robot, state, {}, h.seq, why)
        return [Send(h.origin, final), *self.drop(execution, why)]

    def unsendable(self, execution: ExecutionId, why: str) -> list[Effect]:
        """A status of the run could not be sent (its outputs do not encode): the run
        fails, and its origin hears that instead, now and when it asks again."""
        if execution in self.hosted:
            return self.give_up(execution, why, RunState.FAILED)
        final = self.finished.get(execution)
        if final is None or final.detail == why:
            return []
        failed = ExecutionStatus(execution, self.robot, RunState.FAILED, {}, final.seq, why)
        self.finished[execution] = failed
        return [Send(execution.origin, failed)]

    # -- ending -----------------------------------------------------------------------
    def release(self, execution: ExecutionId) -> list[Effect]:
        """A run of this robot's body ended (hosted or its own): the queued one starts."""
        nxt = self.body.release(execution)
        return [Start(nxt)] if nxt is not None else []

    def drop(self, execution: ExecutionId, why: str) -> list[Effect]:
        h = self.hosted.pop(execution, None)
        if h is None:
            return []
        return [Drop(execution, why, h.run), *self.release(execution)]

    def _drop_all(self, executions: list[ExecutionId], why: str) -> list[Effect]:
        # The queued one first: it must not start on the way.
        executions.sort(key=lambda e: e != self.body.queued)
        out: list[Effect] = []
        for execution in executions:
            out += self.drop(execution, why)
        return out

    def origin_gone(self, robot: str, why: str) -> list[Effect]:
        return self._drop_all([e for e, h in self.hosted.items() if h.origin == robot], why)

    def expire(self, now: float) -> list[Effect]:
        """Stop every run whose lease ended, telling the origin of each that acted (so it
        re-assigns the task at once rather than when its own count runs out)."""
        late = [e for e, h in self.hosted.items() if now >= h.until]
        told: list[Effect] = []
        for e in late:
            h = self.hosted[e]
            if h.started:
                why = "origin lease lapsed"
                told.append(
                    Send(h.origin, ExecutionStatus(e, self.robot, RunState.LOST, {}, h.seq, why))
                )
        return [*self._drop_all(late, "origin lease lapsed"), *told]

    def next_end(self) -> float | None:
        """When the earliest lease ends (this robot's clock), or None: nothing hosted."""
        return min((h.until for h in self.hosted.values()), default=None)

    def drop_all(self, why: str) -> list[Effect]:
        return self._drop_all(list(self.hosted), why)

    def keepalives(self, now: float | None = None) -> list[Send]:
        """One keep-alive per origin naming the runs held for it, stamped ``now``."""
        by_robot: dict[str, list[ExecutionId]] = {}
        for e, h in self.hosted.items():
            by_robot.setdefault(h.origin, []).append(e)
        return [
            Send(r, KeepAlive(self.robot, ids, [] if now is None else [now] * len(ids)))
            for r, ids in sorted(by_robot.items())
        ]
