"""The executor's side of mission control: bids, awards and the runs it hosts.

Decisions about leases and the body are the core's (:mod:`btcap.team.core`); this part
knows the robot's implementations, builds runs and loads them into the slot.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

from btcap.bt.state import TreeError
from btcap.team.capabilities.implementation import (
    Implementation,
    ImplementationRun,
    Precondition,
    Scope,
)
from btcap.team.capabilities.runs import RunFactory
from btcap.team.capabilities.slot import RemoteCapabilitySlot
from btcap.team.core.bidding import evaluate
from btcap.team.core.body import Body
from btcap.team.core.bounds import BidBook, Budgets, bid_memory_s
from btcap.team.core.costwatch import CostWatch
from btcap.team.core.effects import Drop, Effect, Send
from btcap.team.core.fence import speedup_of, speedups_differ
from btcap.team.core.hosting import Hosted, HostLeases
from btcap.team.ids import ExecutionId
from btcap.team.membership.repository import CapabilityRepository
from btcap.team.messages import Award, Bid, CallForBids, CostChanged, NoBid
from btcap.team.runtime.stats import MissionStats
from btcap.team.settings import MissionConfig
from btcap.transports.log import get_logger, wanted

__all__ = [
    "CALLS_BURST",
    "CALLS_PER_S",
    "ExecutorSide",
]

log = get_logger(__name__)


#: Calls for bids one auctioneer may have priced at once, then per clock second: a tree
#: that asks for many capabilities in one tick opens as many auctions at once.
CALLS_BURST = 256.0
CALLS_PER_S = 64.0


class ExecutorSide:
    """Bidding and taking awards for one robot, local runs and hosted ones alike."""

    def __init__(
        self,
        robot: str,
        repository: CapabilityRepository,
        body: Body,
        stats: MissionStats,
        now: Callable[[], float],
        *,
        config: MissionConfig | None = None,
    ) -> None:
        cfg = config or MissionConfig()
        self.robot = robot
        self.repository = repository
        self.body = body
        self.stats = stats
        self.now = now
        self.host: HostLeases[ImplementationRun] = HostLeases(
            robot, body, max_lease_s=cfg.max_lease_s
        )
        #: The auctions this robot bid in and the consensus tasks it claimed: the only
        #: awards it takes.
        self.bids = BidBook(bid_memory_s(cfg.auction_window_s, cfg.award_timeout_s))
        #: Calls for bids priced per auctioneer (each costs the implementations' estimates).
        self.calls = Budgets(CALLS_PER_S, CALLS_BURST)
        self.slot: RemoteCapabilitySlot | None = None
        self.runs: RunFactory | None = None
        self._rates_told: set[str] = set()  # origins told their clock rate differs
        #: Runs of this robot's own capability nodes, awarded and not yet adopted.
        self.local_runs: dict[ExecutionId, ImplementationRun] = {}
        self.costs = CostWatch(0.2)

    @property
    def idle(self) -> bool:
        """Whether the robot runs nothing now (bids made while busy include the wait)."""
        return self.body.idle

    def attach_slot(self, slot: RemoteCapabilitySlot) -> None:
        if self.slot is not None and self.slot is not slot:
            raise TreeError(f"robot {self.robot} already has a remote capability slot")
        self.slot = slot

    def unmet(self, preconditions: tuple[Precondition, ...]) -> str | None:
        for p in preconditions:
            ok = (
                p.capability in self.repository.succeeded
                if p.scope is Scope.LOCAL
                else self.repository.succeeded_anywhere(p.capability)
            )
            if not ok:
                return f"precondition {p.capability} ({p.scope.value}) not met"
        return None

    def cost_news(
        self, inputs_of: Callable[[ExecutionId], Mapping[str, Any] | None]
    ) -> list[Effect]:
        """Re-estimate what finishing each run this robot holds would cost (a local run's
        inputs from ``inputs_of``); a rise beyond the margin is news for its origin."""
        runs: dict[ExecutionId, tuple[ImplementationRun, Mapping[str, Any] | None]] = {
            e: (h.run, h.inputs) for e, h in self.host.hosted.items()
        }
        runs.update({e: (r, inputs_of(e)) for e, r in self.local_runs.items()})
        self.costs.keep_only(runs)
        out: list[Effect] = []
        for execution, (run, inputs) in runs.items():
            if inputs is None:
                continue
            impl = run.implementation
            try:
                cost = impl.cost(impl.interface.convert_inputs(dict(inputs), execution.__str__))
            except Exception as exc:  # a broken estimate is no news; the run goes on
                self.stats.errors += 1
                log.error(
                    "mission.cost_failed", robot=self.robot, implementation=impl.name, exc_info=exc
                )
                continue
            if cost is None:
                continue
            self.body.estimate(execution, cost)  # what a task queued behind it waits
            if self.costs.see(execution, cost):
                out.append(Send(execution.origin, CostChanged(execution, cost)))
        return out

    def evaluate(self, cfb: CallForBids) -> Bid | NoBid:
        """This robot's answer to a call for bids (reserves nothing); its auctioneer is
        the sender (checked by the caller: a call's sender, a consensus task's origin)."""
        if (why := self._other_rate(cfb.auction.auctioneer, cfb.speedup)) is not None:
            return NoBid(cfb.auction, self.robot, why)
        impls = self.repository.local_implementations(cfb.interface, cfb.identity)
        holding = cfb.holder is not None and self.body.holds(cfb.holder)
        handing = (
            cfb.handing is not None
            and cfb.handing == self.body.running
            and self.body.queued is None
            and cfb.handing.origin == cfb.auction.auctioneer != self.robot
        )
        # re-evaluated: what is left; an exchange: as if it handed its own over
        wait = 0.0 if holding or handing else self.body.wait_cost()
        # time-extended: too busy to take it, it says what the task would cost it later
        later = wait is None and cfb.extended and cfb.holder is None and cfb.handing is None
        if later:
            wait = self.body.committed_cost()
        if not impls or wait is None:
            return NoBid(cfb.auction, self.robot, "busy" if impls else "no matching implementation")
        if self.slot is None and cfb.auction.auctioneer != self.robot:
            return NoBid(cfb.auction, self.robot, "no remote capability slot")
        try:
            inputs = impls[0].interface.convert_inputs(
                cfb.inputs, lambda: f"call for bids {cfb.auction}"
            )
        except TreeError as exc:
            return NoBid(cfb.auction, self.robot, str(exc))
        ev = evaluate(
            cfb,
            self.robot,
            impls,
            inputs,
            wait=wait,
            unmet=lambda i: self.unmet(i.preconditions),
            later=later,
        )
        for name, err in ev.errors:
            self.stats.errors += 1
            log.error("mission.bid_failed", robot=self.robot, implementation=name, exc_info=err)
        return ev.answer

    def bid(self, sender: str, cfb: CallForBids) -> Bid | NoBid | None:
        """This robot's answer to ``sender``'s call for bids, remembered so its award is
        taken; None: over the auctioneer's budget of calls (not answered: the auction
        closes at its window)."""
        now = self.now()
        if not self.calls.allow(sender, now):
            return None
        answer = self.evaluate(cfb)  # (one on a clock of another speed-up declines)
        if isinstance(answer, Bid):
            self.bids.bid(cfb.auction, cfb.interface, now)
        return answer

    def claimed(self, execution: ExecutionId) -> None:
        self.bids.claimed(execution, self.now())

    def _implementation(self, msg: Award) -> Implementation | str:
        impls = self.repository.local_implementations(msg.interface)
        impl = next((i for i in impls if i.name == msg.implementation), None)
        if impl is None:
            return f"no implementation {msg.implementation!r}"
        if msg.execution.origin != self.robot and self.slot is None:
            return "no remote capability slot"
        return self.unmet(impl.preconditions) or impl

    def _other_rate(self, sender: str, theirs: float) -> str | None:
        """Why not, if the origin's clock runs at another speed-up than ours: its lease
        would end there long before (or after) it ends here (logged once per origin)."""
        ours = speedup_of(self.runs.system.clock) if self.runs is not None else 0.0
        if not speedups_differ(ours, theirs):
            return None
        why = (
            f"clock speed-up {ours:g} here and {theirs:g} at {sender}: every robot of "
            "a team runs at the same one (timing.speedup in each agent file), or a run "
            "could act after its origin gave it up"
        )
        if sender not in self._rates_told:
            if len(self._rates_told) >= 256:  # (bounded: a line again now and then)
                self._rates_told.clear()
            self._rates_told.add(sender)
            log.error("mission.speedup_differs", robot=self.robot, origin=sender, detail=why)
        return why

    def accept(self, sender: str, msg: Award) -> str | None:
        """Take the award, or say why not; nothing is held after a refusal."""
        if self.host.repeated(sender, msg):  # a copy of one we hold (the network's)
            return None
        refused = self.bids.refuse(sender, msg, self.now()) or self.host.refuse_award(sender, msg)
        impl = refused or self._other_rate(sender, msg.speedup) or self._implementation(msg)
        if isinstance(impl, str):
            return impl
        assert self.runs is not None
        try:
            inputs = impl.interface.convert_inputs(msg.inputs, lambda: f"award {msg.execution}")
            cost = impl.cost(inputs)
            if cost is None:
                return f"{impl.name}: {impl.why_no_cost()}"
            run = self.runs.take(impl, msg.execution)
        except Exception as exc:  # a broken implementation declines, never kills the actor
            if not isinstance(exc, TreeError | ValueError):
                self.stats.errors += 1
                log.error(
                    "mission.build_failed", robot=self.robot, implementation=impl.name, exc_info=exc
                )
            return str(exc)
        self.bids.taken(msg)
        if msg.execution.origin != self.robot:
            if self.host.admit(msg, run, inputs, cost, self.now()):
                why = self.load(msg.execution)
                if why is not None:
                    self.host.drop(msg.execution, why)
                    self.runs.close(run)
                    return why
            self.stats.hosted += 1
            return None
        self.body.take(msg.execution, cost)
        self.local_runs[msg.execution] = run
        try:
            run.tree.setup()
        except Exception as exc:
            self.local_runs.pop(msg.execution)
            self.body.release(msg.execution)
            self.runs.close(run)
            return f"setup of {impl.name!r} failed: {exc}"
        return None

    def load(self, execution: ExecutionId) -> str | None:
        """Put a hosted run that now has the body into the slot, or say why it cannot."""
        h = self.host.hosted[execution]
        try:
            return self.slot.load(h) if self.slot is not None else "no remote capability slot"
        except Exception as exc:
            return f"setup of {h.run.implementation.name!r} failed: {exc}"

    def start(self, execution: ExecutionId) -> list[Effect]:
        """The body came free for a queued run (a local one is ticked by its own node)."""
        if execution not in self.host.hosted:
            return []
        why = self.load(execution)
        return [] if why is None else self.host.give_up(execution, why)

    def drop(self, e: Drop) -> None:
        """Stop and remove a run the core dropped."""
        if self.slot is not None:
            self.slot.unload(e.execution, e.why)
        if wanted("btcap.mission", logging.INFO):  # once a round, on the winner
            log.info("mission.hosted_done", robot=self.robot, execution=str(e.execution), why=e.why)
        self.close(e.run)

    def close(self, run: ImplementationRun) -> None:
        if self.runs is not None:
            self.runs.close(run)

    def convert(self, h: Hosted[ImplementationRun], values: dict[str, Any]) -> dict[str, Any] | str:
        try:
            return h.run.implementation.interface.convert_inputs(values, f"execution {h.execution}")
        except TreeError as exc:
            return str(exc)
