"""Both sides of an execution driven together on explicit time, with the crossings of
messages and timers that matter (no clock, no sockets: every step is chosen here)."""

from __future__ import annotations

from typing import Any

from btcap.team.core.body import Body
from btcap.team.core.effects import Drop, Effect, Lost, Send
from btcap.team.core.hosting import Hosted, HostLeases
from btcap.team.core.members import MemberTable
from btcap.team.core.origin import OriginLeases
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Award,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    RunState,
)

E1 = ExecutionId("a", "root/count", 1)


def lost(execution: ExecutionId, executor: str, why: str) -> list[Effect]:
    """What losing an execution decides: re-assign it, and stop the old run if it hears."""
    stop = CancelExecution(execution, f"re-assigned: {why}")
    return [Lost(execution, executor, why), Send(executor, stop)]


def same(h: Hosted[str], values: dict[str, Any]) -> dict[str, Any] | str:
    return dict(values)


def awarded(lease_s: float = 1.0) -> tuple[OriginLeases, HostLeases[str], Award]:
    award = Award(AuctionId("a", 1), E1, "Count", "impl", {}, lease_s)
    return OriginLeases("a"), HostLeases("b", Body()), award


def deliver_to_origin(origin: OriginLeases, effects: list[Effect], now: float) -> list[Effect]:
    out: list[Effect] = []
    for e in effects:
        assert isinstance(e, Send)
        assert isinstance(e.message, ExecutionStatus)
        out += origin.status("b", e.message, now)
    return out


def test_award_and_lease_expiry_crossing() -> None:
    """The accept reached the origin late, and its first inputs later still: the executor
    gave the (never started) run up first, so when the inputs come it says so and the
    origin re-assigns at once, without waiting for its own (later) lease expiry. Nothing
    ran twice: the run never acted."""
    origin, host, award = awarded(lease_s=1.0)
    assert host.refuse_award("a", award) is None
    host.admit(award, "run", {}, 1.0, now=0.0)
    origin.track(E1, "b", 1.0, now=0.5, stamp=0.0)  # the accept arrived at 0.5
    assert host.expire(0.9) == [Drop(E1, "origin lease lapsed", "run")]
    assert host.body.idle  # b no longer runs it ...
    assert origin.expire(0.85) == []  # ... while a still believes it does
    answer = host.inputs("a", ExecutionInputs(E1, 1, {}, 0.0), 0.95, same)
    assert deliver_to_origin(origin, answer, 0.95) == lost(
        E1, "b", "executor no longer has it (unknown execution)"
    )


def test_a_decline_after_the_auctioneer_timed_out() -> None:
    """The award reply was too late: the auctioneer withdrew the award (a cancel) and
    went on to the next bidder. Whether the late reply was an accept or a decline, the
    executor ends up not running it, and the origin never tracked it."""
    origin, host, award = awarded()
    host.admit(award, "run", {}, 1.0, now=0.0)  # it accepted, but the reply was lost
    assert host.cancel("a", CancelExecution(E1, "award withdrawn")) == [
        Drop(E1, "award withdrawn", "run")
    ]
    assert E1 not in origin.tracked
    assert host.body.idle
    # A status the executor sent before the withdrawal reached it changes nothing.
    stale = ExecutionStatus(E1, "b", RunState.RUNNING, {}, 0)
    assert origin.status("b", stale, now=0.1) == []
    assert E1 not in origin.tracked


def test_a_heartbeat_from_a_robot_already_declared_dead() -> None:
    """b stalls past the failure timeout: the origin re-assigns its work. b's heartbeat
    then comes back: it rejoins, but its old run is stopped, not trusted."""
    members = MemberTable("a")
    origin, host, award = awarded(lease_s=2.0)
    members.heartbeat("b", 7, 0, now=0.0)
    host.admit(award, "run", {}, 1.0, now=0.0)
    origin.track(E1, "b", 2.0, now=0.0)
    members.suspect("b", 7, 0, "a", now=0.1)
    assert members.expire(0.6, lambda _s: 0.5) == ["b"]
    assert origin.member_gone("b", "robot b failed") == lost(E1, "b", "robot b failed")
    members.heartbeat("b", 7, 0, now=0.7)
    assert "b" in members.alive()
    report = host.ticked(E1, RunState.RUNNING, {"y": 1})
    [stop] = deliver_to_origin(origin, report, 0.7)
    assert stop == Send("b", CancelExecution(E1, "no longer assigned to you"))
    assert host.cancel("a", stop.message) == [Drop(E1, "no longer assigned to you", "run")]
    assert host.body.idle


def test_a_duplicate_result_after_the_executor_finished() -> None:
    origin, host, award = awarded()
    host.admit(award, "run", {}, 1.0, now=0.0)
    t = origin.track(E1, "b", 1.0, now=0.0)
    done = host.ticked(E1, RunState.SUCCEEDED, {"y": 3})
    assert deliver_to_origin(origin, done[:1], 0.1) == []
    assert t.state is RunState.SUCCEEDED
    # The origin's last inputs crossed the result: the executor repeats the result.
    again = host.inputs("a", ExecutionInputs(E1, 2, {}), 0.2, same)
    assert deliver_to_origin(origin, again, 0.2) == []
    assert (t.state, t.outputs, t.lost) == (RunState.SUCCEEDED, {"y": 3}, False)
