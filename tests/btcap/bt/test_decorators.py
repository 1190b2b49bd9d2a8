"""Decorators: remapping, retrying, repeating, timing (on a ManualClock) and running once.

Every tick goes through ``tick_checked`` (the halting invariant holds after each one).
"""

from __future__ import annotations

import asyncio
from typing import Any

import anyio
import pytest
from structlog.testing import capture_logs

from btcap import (
    Action,
    AlwaysRunning,
    Delay,
    FailureIsRunning,
    ForceFailure,
    ForceSuccess,
    Inverter,
    Leaf,
    Node,
    ReactiveFallback,
    Repeat,
    RepeatUntilFailure,
    RepeatUntilSuccess,
    Retry,
    RunningIsFailure,
    RunningIsSuccess,
    RunOnce,
    Sequence,
    SuccessIsRunning,
    Throttle,
    Timeout,
    Tree,
    TreeError,
)
from btcap import State as St
from btcap.actors import ManualClock
from btcap.bt.decorators import Decorator, Remap
from btcap.bt.invariants import tick_checked as tick

S, F, R = St.SUCCEEDED, St.FAILED, St.RUNNING


class Leafy(Leaf):
    """Returns the next scripted result (the last one repeats); counts ticks, unticks and
    resets."""

    def __init__(self, *script: St, name: str = "child") -> None:
        super().__init__(name)
        self.script = list(script)
        self.ticks = 0
        self.unticks = 0
        self.resets = 0

    def on_tick(self) -> St:
        self.ticks += 1
        if len(self.script) > 1:
            return self.script.pop(0)
        return self.script[0]

    def on_untick(self) -> None:
        self.unticks += 1

    def on_reset(self) -> None:
        self.resets += 1


def run(tree: Tree, n: int) -> list[St]:
    return [tick(tree) for _ in range(n)]


# -- remapping --------------------------------------------------------------------------

REMAPS: dict[type[Decorator], dict[St, St]] = {
    Inverter: {S: F, F: S, R: R},
    ForceSuccess: {S: S, F: S, R: R},
    ForceFailure: {S: F, F: F, R: R},
    RunningIsSuccess: {S: S, F: F, R: S},
    RunningIsFailure: {S: S, F: F, R: F},
    SuccessIsRunning: {S: R, F: F, R: R},
    FailureIsRunning: {S: S, F: R, R: R},
}
# How each child state is seen by a decorator: waiting counts as running, error as failure.
SEEN = {
    S: S,
    F: F,
    R: R,
    St.UNASSIGNED: R,
    St.ASSIGNED: R,
    St.PAUSED: R,
    St.ERROR: F,
}


@pytest.mark.parametrize("kind", list(REMAPS), ids=lambda k: k.__name__)
@pytest.mark.parametrize("child_state", list(SEEN), ids=lambda s: s.value)
def test_remapping_decorators(kind: type[Decorator], child_state: St) -> None:
    child = Leafy(child_state)
    tree = Tree(kind("dec", children=[child]))
    result = tick(tree)
    assert result is REMAPS[kind][SEEN[child_state]]
    active = child_state in (R, St.UNASSIGNED, St.ASSIGNED)
    # A result given for a child still at work ends that work: the child is unticked.
    assert child.state is (St.PAUSED if active and result is not R else child_state)


@pytest.mark.parametrize("kind", [RunningIsSuccess, RunningIsFailure])
def test_running_is_result_unticks_the_child_the_same_tick(kind: type[Decorator]) -> None:
    # ReactiveFallback(a, RunningIsSuccess(b)), a failing, b running: b must not stay RUNNING
    # after its branch gave a result (it used to, neither ticked nor halted).
    a, b = Leafy(F, name="a"), Leafy(R, name="b")
    dec = kind("dec", children=[b])
    tree = Tree(Sequence("root", children=[ReactiveFallback("fb", children=[a, dec])]))
    expected = S if kind is RunningIsSuccess else F
    assert tick(tree) is expected
    assert b.state is St.PAUSED
    assert b.unticks == 1
    assert tick(tree) is expected  # ticked again: b resumes and is unticked again
    assert (b.ticks, b.unticks) == (2, 2)


async def test_running_is_success_cancels_the_abandoned_action() -> None:
    with anyio.fail_after(5):
        seen: list[str] = []

        async def work() -> None:
            await asyncio.sleep(0)
            seen.append("ran to completion")

        act = Action(work, "act")
        tree = Tree(
            Sequence(
                "root", children=[RunningIsSuccess("dec", children=[act]), Leafy(R, name="next")]
            )
        )
        assert tick(tree) is R
        for _ in range(5):
            await asyncio.sleep(0)
        assert seen == []  # its branch moved on: the work was cancelled, not left running
        assert act.state is St.PAUSED
        await tree.shutdown()


def test_own_remaps_and_hand_written_ticks_of_remap_subclasses() -> None:
    class WaitingIsFailure(Remap):
        MAP = {R: F, F: S}

    class LoudInverter(Inverter):
        def on_tick(self) -> St:
            self.seen = super().on_tick()
            return self.seen

    class Sub(WaitingIsFailure): ...

    child = Leafy(R)
    assert tick(Tree(Sub("d", children=[child]))) is F
    assert child.state is St.PAUSED
    loud = LoudInverter("inv", children=[Leafy(S)])
    assert tick(Tree(loud)) is F
    assert loud.seen is F


def test_decorator_counts_error_of_a_raising_child_as_failure() -> None:
    class Boom(Leaf):
        def on_tick(self) -> St:
            raise RuntimeError("boom")

    tree = Tree(Inverter("inv", children=[Boom("boom")]))
    with capture_logs():
        assert tick(tree) is S
    assert tree.errors()[0].name == "boom"


@pytest.mark.parametrize("kind", [Inverter, Retry, Repeat, Timeout, RunOnce])
def test_decorators_need_exactly_one_child(kind: type[Node]) -> None:
    opts: dict[str, Any] = {"seconds": 1.0} if kind is Timeout else {}
    with pytest.raises(TreeError, match="at most 1 children"):
        kind("d", children=[Leafy(S, name="a"), Leafy(S, name="b")], **opts)
    tree = Tree(kind("d", **opts))
    with pytest.raises(TreeError, match="has 0 children; expected 1 to 1"):
        tick(tree)


def test_decorator_child_property() -> None:
    child = Leafy(S)
    assert Inverter("inv", children=[child]).child is child


# -- retry / repeat -----------------------------------------------------------------------


def test_retry_re_runs_a_failing_child() -> None:
    child = Leafy(F, F, S)
    tree = Tree(Retry("retry", children=[child], retries=2))
    assert run(tree, 3) == [R, R, S]
    assert child.ticks == 3
    assert child.resets == 2  # fresh start for every new attempt


def test_retry_gives_up_after_the_retries() -> None:
    child = Leafy(F)
    tree = Tree(Retry("retry", children=[child], retries=2))
    assert run(tree, 3) == [R, R, F]
    assert child.ticks == 3
    assert run(tree, 3) == [R, R, F]  # the count starts over


def test_retry_default_is_one_retry_and_running_passes_through() -> None:
    child = Leafy(R, F, R, F)
    tree = Tree(Retry("retry", children=[child]))
    assert run(tree, 4) == [R, R, R, F]


def test_retry_success_resets_the_count() -> None:
    child = Leafy(F, S, F, S)
    tree = Tree(Retry("retry", children=[child], retries=1))
    assert run(tree, 4) == [R, S, R, S]


def test_retry_counts_errors_as_failures() -> None:
    class Flaky(Leaf):
        def __init__(self) -> None:
            super().__init__("flaky")
            self.calls = 0

        def on_tick(self) -> St:
            self.calls += 1
            if self.calls == 1:
                raise OSError("transient")
            return S

    flaky = Flaky()
    tree = Tree(Retry("retry", children=[flaky], retries=1))
    with capture_logs():
        assert run(tree, 2) == [R, S]
    assert flaky.error is None  # reset between attempts


def test_repeat_n_times() -> None:
    child = Leafy(S)
    tree = Tree(Repeat("rep", children=[child], times=3))
    assert run(tree, 3) == [R, R, S]
    assert child.resets == 2
    assert run(tree, 3) == [R, R, S]


def test_repeat_waits_for_a_running_child_and_fails_on_failure() -> None:
    child = Leafy(R, S, F)
    tree = Tree(Repeat("rep", children=[child], times=3))
    assert run(tree, 3) == [R, R, F]


def test_repeat_default_once() -> None:
    assert tick(Tree(Repeat("rep", children=[Leafy(S)]))) is S


def test_repeat_forever() -> None:
    child = Leafy(S)
    tree = Tree(Repeat("rep", children=[child], times=-1))
    assert set(run(tree, 200)) == {R}
    assert child.ticks == 200


def test_repeat_until_success() -> None:
    child = Leafy(F, F, R, S)
    tree = Tree(RepeatUntilSuccess("rus", children=[child]))
    assert run(tree, 4) == [R, R, R, S]


def test_repeat_until_success_unbounded() -> None:
    tree = Tree(RepeatUntilSuccess("rus", children=[Leafy(F)]))
    assert set(run(tree, 100)) == {R}


def test_repeat_until_success_max_attempts() -> None:
    child = Leafy(F)
    tree = Tree(RepeatUntilSuccess("rus", children=[child], max_attempts=3))
    assert run(tree, 3) == [R, R, F]
    assert child.ticks == 3
    assert run(tree, 3) == [R, R, F]


def test_repeat_until_failure() -> None:
    child = Leafy(S, R, S, F)
    tree = Tree(RepeatUntilFailure("ruf", children=[child]))
    assert run(tree, 4) == [R, R, R, S]


def test_repeat_until_failure_max_attempts() -> None:
    child = Leafy(S)
    tree = Tree(RepeatUntilFailure("ruf", children=[child], max_attempts=2))
    assert run(tree, 2) == [R, F]


def test_counts_are_forgotten_on_reset() -> None:
    tree = Tree(Repeat("rep", children=[Leafy(S)], times=2))
    assert tick(tree) is R
    tree.reset()
    assert run(tree, 2) == [R, S]


def test_retry_keeps_its_count_across_an_untick_and_forgets_it_on_reset() -> None:
    child = Leafy(F, R)
    tree = Tree(Retry("retry", children=[child], retries=1))
    assert run(tree, 2) == [R, R]  # one retry used, the second attempt running
    tree.untick()
    assert child.state is St.PAUSED
    child.script = [F]
    assert tick(tree) is F  # resumed: the used retry still counts
    child.script = [F, R]
    assert run(tree, 2) == [R, R]
    tree.untick()
    tree.reset()  # restart: the full budget again
    child.script = [F]
    assert run(tree, 2) == [R, F]


def test_repeat_keeps_its_count_across_an_untick_and_forgets_it_on_reset() -> None:
    child = Leafy(S, S, R)
    tree = Tree(Repeat("rep", children=[child], times=3))
    assert run(tree, 3) == [R, R, R]  # two successes counted, the third run going on
    tree.untick()
    child.script = [S]
    assert tick(tree) is S  # resumed: the third success completes it
    child.script = [S, S, R]
    assert run(tree, 3) == [R, R, R]
    tree.untick()
    tree.reset()
    child.script = [S]
    assert run(tree, 3) == [R, R, S]


@pytest.mark.parametrize(
    ("kind", "option", "value"),
    [(Retry, "retries", "x"), (Repeat, "times", 1.5), (RepeatUntilSuccess, "max_attempts", "a")],
)
def test_counting_options_are_type_checked(kind: type[Node], option: str, value: Any) -> None:
    with pytest.raises(TreeError, match=f"option '{option}': expected int"):
        kind("d", children=[Leafy(S)], **{option: value})


@pytest.mark.parametrize(
    ("kind", "option", "bad", "rule", "fine"),
    [
        (Retry, "retries", -1, ">= 0", 0),
        (Repeat, "times", -2, ">= -1", -1),  # -1: for ever
        (RepeatUntilSuccess, "max_attempts", 0, ">= 1", 1),
        (RepeatUntilFailure, "max_attempts", -1, ">= 1", None),  # None: no limit
        (Timeout, "seconds", 0, "> 0", 0.001),
        (Timeout, "seconds", -5, "> 0", 0.001),
        (Delay, "seconds", -5, ">= 0", 0),
        (Delay, "seconds", float("nan"), ">= 0", float("inf")),
        (Throttle, "rate_hz", -1, "> 0", 0.5),
    ],
)
def test_negative_counts_and_durations_are_refused_naming_node_and_option(
    kind: type[Node], option: str, bad: Any, rule: str, fine: Any
) -> None:
    with pytest.raises(TreeError) as err:
        kind("d", children=[Leafy(S)], **{option: bad})
    assert str(err.value) == f"node 'd' option {option!r}: must be {rule}, got {bad!r}"
    assert kind("d", children=[Leafy(S)], **{option: fine}).options[option] == fine


# -- time -------------------------------------------------------------------------------


async def test_timeout_fails_and_unticks_a_slow_child() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(R)
        tree = Tree(Timeout("to", children=[child], seconds=2), clock=clock)
        assert tick(tree) is R
        await clock.advance(1.9)
        assert tick(tree) is R
        assert child.ticks == 2
        await clock.advance(0.1)
        assert tick(tree) is F
        assert child.state is St.PAUSED
        assert child.ticks == 2
        # A new tick starts a new period.
        assert tick(tree) is R
        await clock.advance(1.0)
        assert tick(tree) is R


async def test_timeout_passes_a_timely_result_through() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(R, R, S)
        tree = Tree(Timeout("to", children=[child], seconds=2), clock=clock)
        assert tick(tree) is R
        await clock.advance(1.5)
        assert tick(tree) is R
        assert tick(tree) is S
        await clock.advance(1.0)  # the period started over when the child finished
        child.script = [F]
        assert tick(tree) is F


async def test_timeout_restarts_after_untick_and_reset() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(Timeout("to", children=[Leafy(R)], seconds=2), clock=clock)
        tick(tree)
        await clock.advance(1.5)
        tree.untick()
        assert tick(tree) is R
        await clock.advance(1.5)
        assert tick(tree) is R
        tree.reset()
        await clock.advance(1.9)
        assert tick(tree) is R


async def test_delay_waits_before_ticking_the_child() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(S)
        tree = Tree(Delay("delay", children=[child], seconds=1.5), clock=clock)
        assert tick(tree) is R
        await clock.advance(1.0)
        assert tick(tree) is R
        assert child.ticks == 0
        await clock.advance(0.5)
        assert tick(tree) is S
        assert child.ticks == 1
        assert tick(tree) is R  # the next run waits again
        await clock.advance(1.5)
        assert tick(tree) is S


async def test_delay_keeps_ticking_a_running_child() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(R, R, F)
        tree = Tree(Delay("delay", children=[child], seconds=1), clock=clock)
        tick(tree)
        await clock.advance(1)
        assert run(tree, 3) == [R, R, F]


async def test_delay_keeps_the_time_waited_across_an_untick_not_the_pause() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(S)
        tree = Tree(Delay("delay", children=[child], seconds=1), clock=clock)
        assert tick(tree) is R
        await clock.advance(0.5)
        tree.untick()  # 0.5 s waited
        await clock.advance(5.0)  # paused: not waiting
        assert tick(tree) is R
        await clock.advance(0.25)
        assert tick(tree) is R  # 0.75 s waited
        assert child.ticks == 0
        await clock.advance(0.25)
        assert tick(tree) is S
        assert child.ticks == 1


async def test_delay_waits_afresh_after_its_result_and_after_two_pauses() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(S)
        tree = Tree(Delay("delay", children=[child], seconds=1), clock=clock)
        for _ in range(2):
            assert tick(tree) is R
            await clock.advance(0.5)
            tree.untick()
            tree.untick()  # a second untick while paused adds nothing
            await clock.advance(3.0)
            assert tick(tree) is R
            await clock.advance(0.25)
            tree.untick()  # 0.75 s waited in two stretches
            await clock.advance(3.0)
            assert tick(tree) is R
            await clock.advance(0.25)
            assert tick(tree) is S
        assert child.ticks == 2


async def test_delay_forgets_on_reset() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(Delay("delay", children=[Leafy(S)], seconds=1), clock=clock)
        tick(tree)
        await clock.advance(0.9)
        tree.reset()
        await clock.advance(0.2)
        assert tick(tree) is R


async def test_throttle_limits_child_ticks_and_repeats_its_state() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        child = Leafy(R, S)
        tree = Tree(Throttle("thr", children=[child], rate_hz=2), clock=clock)
        assert tick(tree) is R
        assert tick(tree) is R
        await clock.advance(0.4)
        assert tick(tree) is R
        assert child.ticks == 1
        await clock.advance(0.1)
        assert tick(tree) is S
        assert child.ticks == 2
        assert tick(tree) is S  # repeated without a tick
        assert child.ticks == 2
        await clock.advance(0.5)
        tick(tree)
        assert child.ticks == 3


@pytest.mark.parametrize("rate", [0, -1.0])
def test_throttle_rate_must_be_positive(rate: float) -> None:
    with pytest.raises(TreeError, match=f"node 'thr' option 'rate_hz': must be > 0, got {rate}"):
        Throttle("thr", children=[Leafy(S)], rate_hz=rate)


@pytest.mark.parametrize("kind", [Timeout, Delay])
def test_time_options_are_required_and_checked(kind: type[Node]) -> None:
    with pytest.raises(TreeError, match=r"option 'seconds' \(float\) is required"):
        kind("d", children=[Leafy(S)])
    with pytest.raises(TreeError, match="option 'seconds': expected float, got str"):
        kind("d", children=[Leafy(S)], seconds="soon")
    assert kind("d", children=[Leafy(S)], seconds=2).options["seconds"] == 2.0


# -- run once ---------------------------------------------------------------------------


@pytest.mark.parametrize("result", [S, F])
def test_run_once_keeps_the_first_result(result: St) -> None:
    child = Leafy(R, result, S if result is F else F)
    tree = Tree(RunOnce("once", children=[child]))
    assert run(tree, 4) == [R, result, result, result]
    assert child.ticks == 2
    tree.reset()
    assert tick(tree) is child.script[0]
    assert child.ticks == 3


def test_repeat_zero_times_succeeds_without_ticking_the_child() -> None:
    """As BehaviorTree.CPP's ``<Repeat num_cycles="0">``: nothing to do is done."""
    child = AlwaysRunning("child")
    tree = Tree(Repeat("none", times=0, children=[child]))
    assert tree.tick() is St.SUCCEEDED
    assert child.state is St.IDLE
