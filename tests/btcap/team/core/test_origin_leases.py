"""The origin's lease table on explicit time: renewals, expiry, who may report."""

from __future__ import annotations

from btcap.team.core.auction import REASON_CHARS
from btcap.team.core.effects import Effect, Lost, Refused, Send
from btcap.team.core.origin import ENDED_KEPT, OriginLeases
from btcap.team.ids import ExecutionId
from btcap.team.messages import CancelExecution, ExecutionStatus, KeepAlive, RunState

E1 = ExecutionId("a", "root/count", 1)
E2 = ExecutionId("a", "root/other", 2)


def lost(execution: ExecutionId, executor: str, why: str) -> list[Effect]:
    """What losing an execution decides: re-assign it, and stop the old run if it hears."""
    stop = CancelExecution(execution, f"re-assigned: {why}")
    return [Lost(execution, executor, why), Send(executor, stop)]


def status(execution: ExecutionId, robot: str, state: RunState, seq: int = 0) -> ExecutionStatus:
    return ExecutionStatus(execution, robot, state, {"y": seq}, seq)


def test_reports_renew_the_lease_and_silence_loses_it_once() -> None:
    o = OriginLeases("a")
    t = o.track(E1, "b", 1.0, now=0.0)
    assert o.status("b", status(E1, "b", RunState.RUNNING, 3), now=0.9) == []
    assert (t.state, t.outputs, t.acked) == (RunState.RUNNING, {"y": 3}, 3)
    assert o.expire(1.8) == []  # renewed at 0.9: lapses only after 1.9
    assert o.expire(1.91) == lost(E1, "b", "lease lapsed")
    assert t.lost
    assert E1 not in o.tracked
    assert o.expire(5.0) == []


def test_only_the_executor_reports_on_an_execution() -> None:
    o = OriginLeases("a")
    t = o.track(E1, "b", 1.0, now=0.0)
    forged = status(E1, "b", RunState.SUCCEEDED, 7)
    [refused] = o.status("mallory", forged, now=0.5)
    assert isinstance(refused, Refused)
    assert refused.sender == "mallory"
    assert t.state is RunState.ASSIGNED  # nothing taken from it
    assert o.expire(1.01) == lost(E1, "b", "lease lapsed")  # and the lease was not renewed


def test_keepalives_renew_only_from_the_executor() -> None:
    o = OriginLeases("a")
    o.track(E1, "b", 1.0, now=0.0, stamp=10.0)
    o.track(E2, "c", 1.0, now=0.0, stamp=20.0)
    o.keepalive("b", [E1, E2], now=0.8, stamps=[11.0, 11.0])  # b may not renew c's
    assert o.expire(1.5) == lost(E2, "c", "lease lapsed")
    assert o.keepalives() == [Send("b", KeepAlive("a", [E1], [11.0]))]


def test_a_duplicate_result_is_taken_once() -> None:
    o = OriginLeases("a")
    t = o.track(E1, "b", 1.0, now=0.0)
    assert o.status("b", status(E1, "b", RunState.SUCCEEDED, 4), now=0.1) == []
    assert t.state is RunState.SUCCEEDED
    assert E1 not in o.tracked
    assert o.status("b", status(E1, "b", RunState.FAILED, 5), now=0.2) == []
    assert t.state is RunState.SUCCEEDED
    assert t.outputs == {"y": 4}


def test_the_executor_saying_it_lost_the_run_loses_it() -> None:
    o = OriginLeases("a")
    o.track(E1, "b", 1.0, now=0.0)
    gone = ExecutionStatus(E1, "b", RunState.LOST, {}, 0, "unknown execution")
    why = "executor no longer has it (unknown execution)"
    assert o.status("b", gone, now=0.1) == lost(E1, "b", why)


def test_an_executors_words_are_kept_and_passed_on_cut_to_size() -> None:
    """A member that won a run may say anything in its reports: what it says goes into
    our log line and our cancel back, so it is cut to REASON_CHARS."""
    o = OriginLeases("a")
    t = o.track(E1, "b", 1.0, now=0.0)
    long = "x" * 900_000
    o.status("b", ExecutionStatus(E1, "b", RunState.RUNNING, {}, 1, long), now=0.1)
    assert t.detail == "x" * REASON_CHARS
    gone = ExecutionStatus(E1, "b", RunState.LOST, {}, 2, long)
    why = f"executor no longer has it ({'x' * REASON_CHARS})"
    assert o.status("b", gone, now=0.2) == lost(E1, "b", why)


def test_a_robot_declared_dead_that_reports_again_is_told_to_stop() -> None:
    o = OriginLeases("a")
    o.track(E1, "b", 1.0, now=0.0)
    o.track(E2, "c", 1.0, now=0.0)
    assert o.member_gone("b", "robot b failed") == lost(E1, "b", "robot b failed")
    assert set(o.tracked) == {E2}
    # b was only slow: its heartbeat and its run's report come back after all.
    [stop] = o.status("b", status(E1, "b", RunState.RUNNING, 9), now=0.3)
    assert stop == Send("b", CancelExecution(E1, "no longer assigned to you"))
    # Its final word on the run changes nothing either.
    assert o.status("b", status(E1, "b", RunState.SUCCEEDED, 10), now=0.4) == []


def test_reports_on_other_robots_executions_are_refused() -> None:
    o = OriginLeases("a")
    other = ExecutionId("z", "root/x", 1)
    [refused] = o.status("b", status(other, "b", RunState.RUNNING), now=0.0)
    assert isinstance(refused, Refused)


def test_a_report_that_overtakes_the_accept_is_ignored_not_cancelled() -> None:
    o = OriginLeases("a")
    assert o.status("b", status(E1, "b", RunState.RUNNING, 0), now=0.0) == []
    t = o.track(E1, "b", 1.0, now=0.0)  # the accept arrives after the first report
    assert o.status("b", status(E1, "b", RunState.RUNNING, 1), now=0.1) == []
    assert t.state is RunState.RUNNING


def test_executions_given_up_on_are_remembered_boundedly() -> None:
    o = OriginLeases("a")
    for n in range(ENDED_KEPT + 5):
        e = ExecutionId("a", "n", n)
        o.track(e, "b", 1.0, now=0.0)
        o.forget(e)
    oldest, newest = ExecutionId("a", "n", 0), ExecutionId("a", "n", ENDED_KEPT + 4)
    assert o.status("b", status(oldest, "b", RunState.RUNNING), now=0.0) == []
    assert o.status("b", status(newest, "b", RunState.RUNNING), now=0.0) != []


def test_outputs_are_typed_on_arrival_and_bad_ones_change_nothing() -> None:
    def convert(t: object, values: dict[str, object]) -> dict[str, object] | str:
        y = values.get("y")
        return {"y": int(y)} if isinstance(y, int | float) else f"output 'y': {y!r} is no int"

    o = OriginLeases("a")
    t = o.track(E1, "b", 1.0, now=0.0)
    running = ExecutionStatus(E1, "b", RunState.RUNNING, {"y": 2.0}, 1)
    assert o.status("b", running, 0.5, convert) == []
    assert t.outputs == {"y": 2}
    [refused] = o.status(
        "b", ExecutionStatus(E1, "b", RunState.SUCCEEDED, {"y": "x"}, 2), 0.9, convert
    )
    assert isinstance(refused, Refused)
    assert (t.state, t.outputs) == (RunState.RUNNING, {"y": 2})
    assert o.expire(1.6) != []  # the bad report did not renew the lease (0.5 + 1.0 < 1.6)


def test_losing_an_execution_tells_its_old_executor_to_stop() -> None:
    """Its reports may have been lost while it still hears us: it must not run on beside
    the executor the node picks next."""
    o = OriginLeases("a")
    o.track(E1, "b", 1.0, now=0.0)
    effects = o.expire(1.01)
    assert Send("b", CancelExecution(E1, "re-assigned: lease lapsed")) in effects


def test_a_late_run_of_an_award_nobody_took_or_given_to_another_is_stopped() -> None:
    """An award withdrawn unanswered that reached its robot late runs there: its first
    report is answered with a cancel, not left to its lease."""
    o = OriginLeases("a")
    o.abandon(E1)  # nobody took it
    stop = CancelExecution(E1, "no longer assigned to you")
    assert o.status("b", status(E1, "b", RunState.RUNNING), now=1.0) == [Send("b", stop)]
    assert o.status("b", status(E1, "b", RunState.SUCCEEDED), now=1.0) == []  # not credited
    o.track(E2, "c", 1.0, now=0.0)  # the next bidder took it
    [refused, cancel] = o.status("b", status(E2, "b", RunState.RUNNING), now=1.0)
    assert isinstance(refused, Refused)
    assert cancel == Send("b", CancelExecution(E2, "assigned to c"))
