"""The fence on explicit time: one task never acts on two robots at once, with message
delays, loss, partitions, a freeze of either side and clocks drifting by up to
:data:`~btcap.team.core.fence.DRIFT` — driven through both sides' real lease tables."""

from __future__ import annotations

import heapq
import math
import random
from dataclasses import dataclass, field
from typing import Any

import msgspec
import pytest

from btcap.team.core.body import Body
from btcap.team.core.effects import Send
from btcap.team.core.fence import DRIFT, EXECUTOR_SHARE, STOP_SLACK, Fences
from btcap.team.core.hosting import Hosted, HostLeases
from btcap.team.core.origin import OriginLeases
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Award,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    RunState,
)

E1 = ExecutionId("a", "root/carry", 1)
E2 = ExecutionId("a", "root/carry", 2)
LEASE = 1.0


def same(h: Hosted[str], values: dict[str, Any]) -> dict[str, Any] | str:
    return dict(values)


def test_the_margin_covers_the_worst_drift() -> None:
    """The executor's run ends, at the worst drift of both clocks, before the origin's
    count ends, with a share of the lease left over to stop it."""
    executor_worst = EXECUTOR_SHARE * LEASE / (1 - DRIFT)  # its clock slow
    origin_soonest = LEASE / (1 + DRIFT)  # its clock fast
    assert origin_soonest - executor_worst == pytest.approx(STOP_SLACK * LEASE)
    assert STOP_SLACK > 0.08


def test_fences_end_at_their_time_or_at_the_robots_word() -> None:
    f = Fences()
    f.hold(E1, "b", 2.0, now=1.0)
    f.hold(E2, "c", 1.5, now=1.0)
    f.hold(E2, "d", 0.9, now=1.0)  # already over: nothing held
    assert f.until("root/carry", 1.2) == 2.0
    f.stopped(E1, "b")
    assert f.until("root/carry", 1.2) == 1.5
    assert f.until("root/other", 1.2) is None
    assert f.until("root/carry", 1.5) is None
    assert len(f) == 0


def test_a_run_cut_off_one_way_stops_though_it_hears_its_origin() -> None:
    """b's reports are lost (a one-way cut): the origin's renewals keep coming but echo
    only b's last stamp it heard, so b stops at that stamp plus its share, on its own."""
    o, h = OriginLeases("a"), HostLeases("b", Body())
    award = Award(AuctionId("a", 1), E1, "Carry", "impl", {}, LEASE)
    assert h.admit(award, "run", {}, 1.0, now=100.0)  # b's clock reads 100 at t=0
    t = o.track(E1, "b", LEASE, now=0.0, stamp=100.0)
    h.inputs("a", ExecutionInputs(E1, 1, {}, t.stamp), 100.01, same)
    stopped = None
    for k in range(1, 30):  # b's reports from t=0.01 on never arrive
        now = 100.0 + 0.05 * k
        h.inputs("a", ExecutionInputs(E1, 1 + k, {}, t.stamp), now, same)
        if h.expire(now):
            stopped = now
            break
    assert stopped == pytest.approx(100.9)  # by its own clock, hearing its origin
    assert o.expire(1.01) != []  # the origin re-assigns then: nothing can still act
    assert o.fenced("root/carry", 1.01) is None


def test_a_renewal_delivered_late_leases_nothing_past_its_echo() -> None:
    h = HostLeases("b", Body())
    award = Award(AuctionId("a", 1), E1, "Carry", "impl", {}, LEASE)
    h.admit(award, "run", {}, 1.0, now=0.0)
    h.keepalive("a", KeepAlive("a", [E1], [0.05]), 0.1)
    # A renewal held 5 s (a frozen link, released in a burst) echoes an old stamp.
    h.keepalive("a", KeepAlive("a", [E1], [0.2]), 5.0)
    assert not h.hosted[E1].leased(5.0)
    assert h.expire(5.0) != []


def test_a_member_declared_failed_fences_its_task_until_its_run_surely_stopped() -> None:
    o = OriginLeases("a")
    t = o.track(E1, "b", LEASE, now=0.0, stamp=7.0)
    o.status("b", ExecutionStatus(E1, "b", RunState.RUNNING, {}, 1, "", 7.3), now=0.3)
    o.member_gone("b", "robot b failed", now=0.8)  # before the lease lapsed
    assert t.lost
    assert o.fenced("root/carry", 0.8) == pytest.approx(1.3)
    assert o.fenced("root/carry", 1.3) is None
    # b was alive after all: its confirmation of the cancel ends the wait early.
    o.member_gone("b", "robot b failed", now=0.8)
    t2 = o.track(E2, "b", LEASE, now=1.0, stamp=8.0)
    o.member_gone("b", "robot b failed", now=1.2)
    assert t2.lost
    assert o.fenced("root/carry", 1.2) == pytest.approx(2.0)
    o.status("b", ExecutionStatus(E2, "b", RunState.LOST, {}, 0, "re-assigned"), now=1.25)
    assert o.fenced("root/carry", 1.25) is None


def test_the_fence_counts_from_when_the_newest_stamp_arrived() -> None:
    """Words without a newer stamp (unstamped, or overtaken) renew nothing on the
    executor, so they do not push the fence back: it opens ``lease_s`` after the newest
    stamp we echo arrived, not after the last word."""
    o = OriginLeases("a")
    t = o.track(E1, "b", LEASE, now=0.0, stamp=7.0)
    o.status("b", ExecutionStatus(E1, "b", RunState.RUNNING, {}, 1, "", 7.2), now=0.2)
    o.status("b", ExecutionStatus(E1, "b", RunState.RUNNING, {}, 2, "", None), now=0.3)
    o.keepalive("b", [E1], now=0.35, stamps=[math.nan])
    o.status("b", ExecutionStatus(E1, "b", RunState.RUNNING, {}, 3, "", 7.1), now=0.4)
    assert (t.stamp, t.last_heard) == (7.2, 0.4)
    o.member_gone("b", "robot b failed", now=0.5)
    assert o.fenced("root/carry", 0.5) == pytest.approx(0.2 + LEASE)


def test_a_moved_run_fences_its_task_until_its_robot_confirms() -> None:
    o, h = OriginLeases("a"), HostLeases("b", Body())
    award = Award(AuctionId("a", 1), E1, "Carry", "impl", {}, LEASE)
    h.admit(award, "run", {}, 1.0, now=0.0)
    o.track(E1, "b", LEASE, now=0.0, stamp=0.0)
    h.keepalive("a", KeepAlive("a", [E1], [0.0]), 0.01)
    o.forget(E1, now=0.5)  # moved: the node cancels it
    assert o.fenced("root/carry", 0.5) == pytest.approx(1.0)
    out = h.cancel("a", CancelExecution(E1, "moved to c"))
    [confirm] = [e for e in out if isinstance(e, Send)]
    o.status("b", confirm.message, now=0.52)
    assert o.fenced("root/carry", 0.52) is None
    # A paused award (never unpaused) and a finished run fence nothing.
    o.track(E2, "c", LEASE, now=1.0, stamp=0.0, paused=True)
    o.forget(E2, now=1.1)
    assert o.fenced("root/carry", 1.1) is None


# -- the property, on random schedules ----------------------------------------------------
@dataclass(order=True)
class _Event:
    at: float
    seq: int
    kind: str = field(compare=False)
    data: Any = field(compare=False, default=None)


@dataclass
class _World:
    """One execution of task ``root/carry`` from a to b, on true time, with faults."""

    rng: random.Random
    lease: float
    fence: bool = True  # False: the origin re-assigns as soon as it gives up (the bug)
    origin_rate: float = 1.0
    executor_rate: float = 1.0
    loss: float = 0.0
    unstamped: float = 0.0  # this share of b's words carry no stamp (renewing nothing)
    delay: float = 0.01
    long_delay: float = 0.0  # some messages are held this long (a burst after a freeze)
    cut: tuple[float, float, str] = (math.inf, math.inf, "both")  # a partition, or one way
    frozen: dict[str, tuple[float, float]] = field(default_factory=dict)
    declare_at: float = math.inf  # the origin's membership declares b failed then
    queue: list[_Event] = field(default_factory=list)
    seq: int = 0
    acting_until: float = -math.inf  # the last true time b's run acted
    started_at: float | None = None  # when the origin let the task's next run start

    def o(self, t: float) -> float:
        return 1000.0 + self.origin_rate * t

    def e(self, t: float) -> float:
        return 50.0 + self.executor_rate * t

    def push(self, at: float, kind: str, data: Any = None) -> None:
        self.seq += 1
        heapq.heappush(self.queue, _Event(at, self.seq, kind, data))

    def send(self, now: float, to: str, msg: Any) -> None:
        start, end, way = self.cut
        if start <= now < end and way in ("both", f"to {to}"):
            return
        if self.rng.random() < self.loss:
            return
        delay = self.rng.uniform(0.0, self.delay)
        if self.long_delay and self.rng.random() < 0.05:
            delay = self.long_delay
        self.push(now + delay, f"to {to}", msg)

    def thawed(self, side: str, t: float) -> float:
        """When ``side`` handles what happens at ``t`` (a frozen side: at its thaw)."""
        start, end = self.frozen.get(side, (math.inf, math.inf))
        return end if start <= t < end else t

    def run(self, until: float = 12.0) -> None:
        origin, host = OriginLeases("a"), HostLeases("b", Body())
        award = Award(AuctionId("a", 1), E1, "Carry", "impl", {}, self.lease)
        host.admit(award, "run", {}, 1.0, self.e(0.0))
        self.send(0.0, "a", ("accept", self.e(0.0)))
        for k in range(1, int(until / 0.1)):
            self.push(k * 0.1 / self.origin_rate, "origin tick")
            self.push(k * 0.1 / self.executor_rate + 0.003, "executor tick")
        self.push(self.declare_at, "declare")
        tracked = None
        step = 0.004
        t = 0.0
        while t < until and self.started_at is None:
            t += step
            # b acts now if its own state says so (a frozen process does nothing).
            h = host.hosted.get(E1)
            if h is not None and h.leased(self.e(t)) and self.thawed("b", t) == t:
                self.acting_until = t
            # b stops a run the moment its lease ends (its timer), unless frozen.
            if self.thawed("b", t) == t:
                for eff in host.expire(self.e(t)):
                    if isinstance(eff, Send):
                        self.send(t, eff.to, eff.message)
            while self.queue and self.queue[0].at <= t:
                ev = heapq.heappop(self.queue)
                side = "a" if ev.kind in ("to a", "origin tick", "declare") else "b"
                if self.thawed(side, ev.at) != ev.at:
                    self.push(self.thawed(side, ev.at), ev.kind, ev.data)
                    continue
                now_o, now_e = self.o(t), self.e(t)
                if ev.kind == "to a":
                    msg = ev.data
                    if isinstance(msg, tuple):  # the award's acceptance
                        tracked = origin.track(E1, "b", self.lease, now_o, stamp=msg[1])
                        self.send(t, "b", KeepAlive("a", [E1], [msg[1]]))
                    elif isinstance(msg, ExecutionStatus):
                        origin.status("b", msg, now_o)
                    else:
                        origin.keepalive("b", msg.executions, now_o, msg.stamps)
                elif ev.kind == "to b":
                    msg = ev.data
                    if isinstance(msg, ExecutionInputs):
                        for eff in host.inputs("a", msg, now_e, same):
                            if isinstance(eff, Send):
                                self.send(t, "a", eff.message)
                    elif isinstance(msg, KeepAlive):
                        host.keepalive("a", msg, now_e)
                    elif isinstance(msg, CancelExecution):
                        for eff in host.cancel("a", msg):
                            if isinstance(eff, Send):
                                self.send(t, "a", eff.message)
                elif ev.kind == "origin tick":
                    if tracked is not None and not tracked.lost:
                        inputs = ExecutionInputs(E1, 1, {}, tracked.stamp)
                        self.send(t, "b", inputs)
                    for eff in origin.expire(now_o):
                        if isinstance(eff, Send):
                            self.send(t, eff.to, eff.message)
                    for keep in origin.keepalives():
                        self.send(t, keep.to, keep.message)
                elif ev.kind == "executor tick" and E1 in host.hosted:
                    report = host.status(host.hosted[E1], now_e)
                    if self.rng.random() < self.unstamped:
                        report = msgspec.structs.replace(report, stamp=None)
                    self.send(t, "a", report)
                    keep = host.keepalives(now_e)
                    for k in keep:
                        msg = k.message
                        if self.rng.random() < self.unstamped:
                            nan = [math.nan] * len(msg.stamps)
                            msg = msgspec.structs.replace(msg, stamps=nan)
                        self.send(t, k.to, msg)
                elif ev.kind == "declare":
                    for eff in origin.member_gone("b", "robot b failed", now_o):
                        if isinstance(eff, Send):
                            self.send(t, eff.to, eff.message)
            gave_up = tracked is not None and tracked.lost
            if gave_up and self.thawed("a", t) == t:
                free = not self.fence or origin.fenced("root/carry", self.o(t)) is None
                if free:
                    self.started_at = t


def _world(seed: int, fence: bool = True) -> _World:
    rng = random.Random(seed)
    w = _World(rng, lease=rng.choice([1.0, 2.5]), fence=fence)
    w.origin_rate = rng.uniform(1 - DRIFT, 1 + DRIFT)
    w.executor_rate = rng.uniform(1 - DRIFT, 1 + DRIFT)
    w.loss = rng.choice([0.0, 0.05, 0.3])
    w.unstamped = rng.choice([0.0, 0.0, 0.5, 0.9])
    w.delay = rng.choice([0.005, 0.05, 0.3])
    w.long_delay = rng.choice([0.0, 0.0, 2.0, 6.0])
    start = rng.uniform(0.5, 4.0)
    w.cut = (start, start + rng.uniform(0.5, 8.0), rng.choice(["both", "to a", "to b"]))
    if rng.random() < 0.3:
        side = rng.choice("ab")
        s = rng.uniform(0.5, 4.0)
        w.frozen[side] = (s, s + rng.uniform(0.2, 5.0))
    w.declare_at = rng.uniform(0.5, 6.0) if rng.random() < 0.7 else math.inf
    return w


def test_never_two_at_once_on_random_schedules() -> None:
    """Over many schedules of delays, loss, partitions (both ways or one), a freeze of
    either side, a false failure declared at any time, and drifting clocks: b's run never
    acts once the origin lets the task's next run start."""
    started = 0
    for seed in range(250):
        w = _world(seed)
        w.run()
        if w.started_at is not None:
            started += 1
            assert w.acting_until < w.started_at, f"seed {seed}: {w}"
    assert started > 180  # the schedules do give the task up, and it does start again


def test_without_the_fence_the_schedules_find_two_at_once() -> None:
    """The same schedules, the origin re-assigning as soon as it gives up (as before the
    fence): some let the new run start while b's still acts."""
    broken = 0
    for seed in range(250):
        w = _world(seed, fence=False)
        w.run()
        if w.started_at is not None and w.acting_until >= w.started_at:
            broken += 1
    assert broken > 10
