"""The award step of every strategy, as pure state (no I/O): award a task to its bidders
in turn until one accepts, and keep why each one did not take it.

An award is an ask: the robot may have become busy since it bid, so it may decline, and
then the next bid is awarded. A robot that does not answer in time is sent the award's
withdrawal, so the task never runs twice. What a peer says about why it declined is
kept to :data:`REASON_CHARS` characters (:func:`bounded`), whatever the strategy.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

from btcap.team.core.auction import REASON_CHARS, AuctionOutcome, bounded
from btcap.team.core.task import Assigned, AssignmentTask, Unassigned
from btcap.team.ids import AuctionId
from btcap.team.messages import Award, Bid, CancelExecution

__all__ = ["REASON_CHARS", "AwardRound", "bounded", "passed_over"]


def passed_over(
    outcome: AuctionOutcome, reserve: float | None, taken: Iterable[str]
) -> dict[str, str]:
    """Why the robots an auction will not award were passed over: they declined, never
    answered, bid above the ``reserve``, or already ``taken`` another task of the batch."""
    taken = set(taken)
    reasons = dict(outcome.declined)
    reasons.update((robot, "no answer") for robot in outcome.silent)
    for bid in outcome.ranking:
        if bid.later:
            reasons[bid.robot] = f"busy (would cost {bid.cost:g} after its current work)"
        elif reserve is not None and bid.cost >= reserve:
            reasons[bid.robot] = f"bid {bid.cost:g} not below {reserve:g}"
        elif bid.robot in taken:
            reasons[bid.robot] = "took another task of the same round"
    return reasons


class AwardRound:
    """One task's award: :meth:`next` is the award to ask the next bidder, best first;
    its answer is told back (:meth:`accepted`, :meth:`declined`, :meth:`unanswered`);
    :meth:`result` says why nobody took it once :meth:`next` gives None.

    ``reasons`` (kept, and filled in place) are why robots were passed over so far.
    """

    def __init__(
        self,
        auction: AuctionId,
        task: AssignmentTask,
        bids: Iterable[Bid],
        reasons: dict[str, str] | None = None,
    ) -> None:
        self.auction = auction
        self.task = task
        self.reasons: dict[str, str] = {} if reasons is None else reasons
        self._bids = deque(bids)
        self._offered: Bid | None = None

    def defer(self, robots: Iterable[str]) -> None:
        """Ask the bids of ``robots`` (suspected of failure now) after all the others: an
        award to a robot likely gone would wait the award timeout for nothing. Their
        order among themselves, and the others', is kept."""
        robots = set(robots)
        if robots:
            bids = list(self._bids)
            first = [b for b in bids if b.robot not in robots]
            self._bids = deque(first + [b for b in bids if b.robot in robots])

    @property
    def offered(self) -> Bid:
        """The bid whose award is being asked."""
        if self._offered is None:
            raise RuntimeError("no award asked: call next() first")
        return self._offered

    def next(self) -> Award | None:
        """The award for the next bidder (its robot: :attr:`offered`), or None: no
        bidder is left."""
        if not self._bids:
            self._offered = None
            return None
        bid = self._offered = self._bids.popleft()
        task = self.task
        return Award(
            self.auction,
            task.execution,
            task.interface,
            bid.implementation,
            dict(task.inputs),
            task.lease_s,
            task.paused,
            task.handing,
        )

    def accepted(self, stamp: float | None = None) -> Assigned:
        """The bidder took the task (its reply stamped ``stamp``, its clock)."""
        bid = self.offered
        return Assigned(bid.robot, bid.implementation, bid.cost, stamp=stamp)

    def declined(self, reason: str) -> str:
        """The bidder declined (it became busy): kept, bounded; returns what was kept."""
        kept = self.reasons[self.offered.robot] = f"declined the award: {bounded(reason)}"
        return kept

    def unanswered(self, why: str) -> CancelExecution:
        """The bidder did not answer in time (or the ask failed, ``why``): the award's
        withdrawal, to send it (it may still take the award after we gave up)."""
        self.reasons[self.offered.robot] = f"no answer to the award ({why})"
        return self.withdrawal()

    def withdrawal(self) -> CancelExecution:
        """What withdraws the award asked (also when we stop waiting for its answer)."""
        return CancelExecution(self.task.execution, "award withdrawn")

    def result(self) -> Unassigned:
        """Nobody took the task, and why."""
        return Unassigned(self.reasons)
