"""The executor's side on explicit time: awards, the origin's messages, leases, the body."""

from __future__ import annotations

from typing import Any

from btcap.team.core.auction import REASON_CHARS
from btcap.team.core.body import Body
from btcap.team.core.effects import Drop, Pause, Refused, Send, Start
from btcap.team.core.hosting import FINISHED_KEPT, Hosted, HostLeases
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import (
    Award,
    CancelExecution,
    ExecutionInputs,
    ExecutionStatus,
    KeepAlive,
    PauseExecution,
    RunState,
)

E1 = ExecutionId("a", "root/count", 1)
E2 = ExecutionId("a", "root/count", 2)
E3 = ExecutionId("c", "root/count", 1)


def award(execution: ExecutionId, lease_s: float = 1.0, paused: bool = False) -> Award:
    return Award(AuctionId(execution.origin, 1), execution, "Count", "impl", {}, lease_s, paused)


def same(h: Hosted[str], values: dict[str, Any]) -> dict[str, Any] | str:
    return dict(values) if "bad" not in values else "input 'bad': expected int"


def host(queue: bool = False) -> HostLeases[str]:
    return HostLeases("b", Body(queue_after_current=queue))


def take(hl: HostLeases[str], execution: ExecutionId, now: float = 0.0, **kw: Any) -> bool:
    a = award(execution, **kw)
    assert hl.refuse_award(execution.origin, a) is None
    return hl.admit(a, f"run-{execution.number}", {}, 1.0, now)


def test_only_the_origin_awards_its_execution() -> None:
    hl = host()
    assert "only its origin" in str(hl.refuse_award("mallory", award(E1)))
    forged = Award(AuctionId("mallory", 1), E1, "Count", "impl", {}, 1.0)
    assert "only its origin" in str(hl.refuse_award("a", forged))


def test_a_busy_body_declines_and_an_award_is_taken_once() -> None:
    hl = host()
    assert take(hl, E1)
    assert "awarded before" in str(hl.refuse_award("a", award(E1)))
    assert "busy" in str(hl.refuse_award("a", award(E2)))


def test_with_a_queue_one_more_waits_and_starts_when_the_body_is_free() -> None:
    hl = host(queue=True)
    assert take(hl, E1) is True
    assert take(hl, E2) is False
    assert hl.body.queued == E2
    assert "busy" in str(hl.refuse_award("c", award(E3)))
    done = ExecutionStatus(E1, "b", RunState.SUCCEEDED, {}, 0)
    assert hl.ticked(E1, RunState.SUCCEEDED, {}) == [
        Send("a", done),
        Drop(E1, "finished", "run-1"),
        Start(E2),
    ]
    assert hl.body.running == E2


def test_inputs_only_from_the_origin_and_answered_at_once() -> None:
    hl = host()
    take(hl, E1)
    [refused] = hl.inputs("mallory", ExecutionInputs(E1, 1, {"x": 1}), 0.1, same)
    assert isinstance(refused, Refused)
    assert hl.hosted[E1].inputs == {}
    [reply] = hl.inputs("a", ExecutionInputs(E1, 2, {"x": 2}), 0.2, same)
    assert reply == Send("a", ExecutionStatus(E1, "b", RunState.ASSIGNED, {}, 2, "", 0.2))
    # An older input arriving late does not overwrite the newer one.
    hl.inputs("a", ExecutionInputs(E1, 1, {"x": 1}), 0.3, same)
    assert (hl.hosted[E1].inputs, hl.hosted[E1].seq) == ({"x": 2}, 2)


def test_malformed_inputs_change_nothing() -> None:
    hl = host()
    take(hl, E1)
    [refused] = hl.inputs("a", ExecutionInputs(E1, 99, {"bad": 1}), 0.5, same)
    assert isinstance(refused, Refused)
    assert "expected int" in refused.why
    assert hl.hosted[E1].seq == 0
    assert hl.expire(0.91) != []  # and it did not renew the lease


def test_inputs_for_an_unknown_or_finished_run_get_its_final_word() -> None:
    hl = host()
    [unknown] = hl.inputs("a", ExecutionInputs(E1, 4, {}), 0.0, same)
    assert unknown == Send("a", ExecutionStatus(E1, "b", RunState.LOST, {}, 4, "unknown execution"))
    take(hl, E1)
    hl.ticked(E1, RunState.FAILED, {"y": 1})
    [final] = hl.inputs("a", ExecutionInputs(E1, 5, {}), 0.1, same)
    assert final == Send("a", ExecutionStatus(E1, "b", RunState.FAILED, {"y": 1}, 0))


def test_finished_statuses_are_bounded() -> None:
    hl = host()
    for n in range(FINISHED_KEPT + 10):
        e = ExecutionId("a", "n", n)
        take(hl, e)
        hl.ticked(e, RunState.SUCCEEDED, {})
    assert len(hl.finished) == FINISHED_KEPT
    assert ExecutionId("a", "n", 0) not in hl.finished


def test_an_award_acts_only_once_renewed_and_stops_at_its_lease_end() -> None:
    """An award alone starts nothing: an unrenewed one (its origin withdrew it, or never
    heard the acceptance) is dropped silently at its lease end; a renewed one acts until
    the echoed stamp plus 0.9 x lease_s, then stops and says so."""
    hl = host()
    take(hl, E1, now=0.0, lease_s=2.0)
    h = hl.hosted[E1]
    assert not h.leased(0.1)
    assert hl.expire(1.79) == []
    assert hl.expire(1.8) == [Drop(E1, "origin lease lapsed", "run-1")]  # never acted
    assert hl.body.idle
    take(hl, E2, now=2.0, lease_s=2.0)
    hl.keepalive("a", KeepAlive("a", [E2], [1.0]), 2.1)  # a stamp from before the award
    assert not hl.hosted[E2].leased(2.1)
    hl.keepalive("a", KeepAlive("a", [E2], [2.5]), 3.9)  # late: counts from its stamp
    assert hl.hosted[E2].leased(3.9)
    assert hl.next_end() == 2.5 + 1.8
    assert hl.expire(4.29) == []
    lapsed = ExecutionStatus(E2, "b", RunState.LOST, {}, 0, "origin lease lapsed")
    assert hl.expire(4.3) == [Drop(E2, "origin lease lapsed", "run-2"), Send("a", lapsed)]


def test_keepalives_and_inputs_renew_only_from_the_origin() -> None:
    hl = host()
    take(hl, E1, now=0.0)
    hl.keepalive("mallory", KeepAlive("mallory", [E1], [0.5]), 0.7)
    hl.keepalive("a", KeepAlive("a", [E1]), 0.7)  # no stamp: no renewal
    assert hl.expire(0.91) == [Drop(E1, "origin lease lapsed", "run-1")]
    take(hl, E2, now=1.0)
    hl.inputs("a", ExecutionInputs(E2, 1, {}, 1.6), 1.7, same)
    assert hl.expire(2.4) == []
    assert hl.keepalives(2.4) == [Send("a", KeepAlive("b", [E2], [2.4]))]


def test_pause_and_cancel_only_from_the_origin() -> None:
    hl = host()
    take(hl, E1)
    assert isinstance(hl.pause("mallory", PauseExecution(E1))[0], Refused)
    assert isinstance(hl.cancel("mallory", CancelExecution(E1))[0], Refused)
    assert hl.pause("a", PauseExecution(E1)) == [Pause(E1)]
    assert hl.hosted[E1].state is RunState.PAUSED
    assert hl.cancel("a", CancelExecution(E1, "reset")) == [Drop(E1, "reset", "run-1")]
    assert hl.cancel("a", CancelExecution(E1, "again")) == []


def test_a_cancel_reason_is_cut_to_size() -> None:
    """The origin's reason goes into our log line and our status back: bounded."""
    hl = host()
    take(hl, E1)
    cut = "r" * REASON_CHARS
    assert hl.cancel("a", CancelExecution(E1, "r" * 900_000)) == [Drop(E1, cut, "run-1")]


def test_a_queued_run_is_not_paused_and_is_dropped_first() -> None:
    hl = host(queue=True)
    take(hl, E1)
    take(hl, E2)
    assert hl.pause("a", PauseExecution(E2)) == []
    # Its origin fails: the queued run goes first, so it never starts on the way.
    assert hl.origin_gone("a", "origin a failed") == [
        Drop(E2, "origin a failed", "run-2"),
        Drop(E1, "origin a failed", "run-1"),
    ]
    assert hl.body.idle
    assert hl.body.queued is None


def test_a_withdrawn_award_frees_the_body() -> None:
    """The auctioneer gave up waiting for the reply (a decline after a timeout, or an
    accept it never saw) and withdraws the award: the executor must not keep it."""
    hl = host()
    take(hl, E1)
    assert hl.cancel("a", CancelExecution(E1, "award withdrawn")) == [
        Drop(E1, "award withdrawn", "run-1")
    ]
    assert hl.refuse_award("a", award(E2)) is None


def test_a_queued_run_that_cannot_start_tells_its_origin() -> None:
    hl = host(queue=True)
    take(hl, E1)
    take(hl, E2)
    hl.ticked(E1, RunState.SUCCEEDED, {})
    lost = ExecutionStatus(E2, "b", RunState.LOST, {}, 0, "slot broken")
    assert hl.give_up(E2, "slot broken") == [
        Send("a", lost),
        Drop(E2, "slot broken", "run-2"),
    ]
    assert hl.body.idle


def test_a_copy_of_an_award_held_is_recognised_to_be_accepted_again() -> None:
    """The network delivered the award twice: declining the copy ("awarded before") let
    the auctioneer give the task to a second robot while the first ran it."""
    hl = host()
    assert not hl.repeated("a", award(E1))
    assert take(hl, E1)
    assert hl.repeated("a", award(E1))
    assert not hl.repeated("mallory", award(E1))  # only from its origin
    assert not hl.repeated("a", award(E2))
    hl.drop(E1, "finished")
    assert not hl.repeated("a", award(E1))
