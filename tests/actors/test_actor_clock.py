"""Explicit time: the sped-up wall clock and the manual clock for tests."""

from __future__ import annotations

import asyncio
import math
import time
from typing import TypeVar

import anyio
import pytest

from btcap.actors import (
    Actor,
    ActorRef,
    ActorSystem,
    AskTimeout,
    Clock,
    ManualClock,
    Message,
    TimeSource,
    handler,
    within,
)
from btcap.transports import InProcessNetwork, MessageRegistry

T = TypeVar("T")


async def _sleeper(
    clock: ManualClock, seconds: float, name: str, woke: list[tuple[str, float]]
) -> None:
    await clock.sleep(seconds)
    woke.append((name, clock.now()))


async def test_manual_clock_wakes_sleepers_in_deadline_order() -> None:
    clock = ManualClock(start=10.0)
    woke: list[tuple[str, float]] = []
    with anyio.fail_after(2):
        async with anyio.create_task_group() as tg:
            # Started in an order that differs from their deadlines.
            tg.start_soon(_sleeper, clock, 3.0, "c", woke)
            tg.start_soon(_sleeper, clock, 1.0, "a", woke)
            tg.start_soon(_sleeper, clock, 2.0, "b", woke)
            tg.start_soon(_sleeper, clock, 2.0, "b2", woke)  # same deadline: FIFO
            await asyncio.sleep(0)  # every sleeper runs up to its sleep
            assert clock.pending == 4
            await clock.advance(0.5)
            assert woke == []
            assert clock.now() == 10.5
            await clock.advance(1.5)  # reaches 12.0: a, b and b2 are due
            assert woke == [("a", 11.0), ("b", 12.0), ("b2", 12.0)]
            assert clock.pending == 1
            await clock.advance(5.0)
            assert woke[-1] == ("c", 13.0)  # each sleeper sees its own deadline as now
            assert clock.now() == 17.0
            assert clock.pending == 0


async def test_manual_clock_wakes_sleepers_that_sleep_again_within_one_advance() -> None:
    clock = ManualClock()
    ticks: list[float] = []

    async def ticker() -> None:
        for _ in range(5):
            await clock.sleep(1.0)
            ticks.append(clock.now())

    with anyio.fail_after(2):
        async with anyio.create_task_group() as tg:
            tg.start_soon(ticker)
            await asyncio.sleep(0)
            assert clock.pending == 1
            await clock.advance(3.5)
            assert ticks == [1.0, 2.0, 3.0]
            await clock.advance(10.0)
            assert ticks == [1.0, 2.0, 3.0, 4.0, 5.0]


async def test_manual_clock_past_deadlines_and_cancelled_sleepers() -> None:
    clock = ManualClock(start=5.0)
    with anyio.fail_after(2):
        await clock.sleep(0)  # returns at once, time does not move
        await clock.sleep(-3)
        await clock.sleep_until(4.0)
        assert clock.now() == 5.0
        task = asyncio.create_task(clock.sleep(1.0))
        await asyncio.sleep(0)
        assert clock.pending == 1
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
        assert clock.pending == 0
        await clock.advance(2.0)  # skips the cancelled sleeper without error
        assert clock.now() == 7.0
    assert clock.speedup == math.inf
    assert clock.to_wall(100.0) == 0.0


class Hop(Message):
    left: int


class Relay(Actor):
    """Passes a hop on to the next relay through an async handler (a mailbox and a task)."""

    def __init__(self, journal: list[str]) -> None:
        super().__init__()
        self.journal = journal
        self.next: ActorRef[Relay] | None = None

    @handler
    async def on_hop(self, msg: Hop) -> None:
        await asyncio.sleep(0)
        self.journal.append(self.address.path)
        if self.next is not None:
            self.next.tell(Hop(msg.left - 1))


async def _handoffs(clock: ManualClock, hops: int, done: list[float]) -> None:
    """Wakes, then passes a token through ``hops`` queues and tasks before recording."""
    queues: list[asyncio.Queue[int]] = [asyncio.Queue() for _ in range(hops + 1)]

    async def relay(i: int) -> None:
        await queues[i + 1].put(await queues[i].get())

    async with anyio.create_task_group() as tg:
        for i in range(hops):
            tg.start_soon(relay, i)
        await clock.sleep(1.0)
        await queues[0].put(1)
        await queues[hops].get()
        done.append(clock.now())


async def test_advance_waits_for_a_long_chain_of_handoffs_after_a_wake_up() -> None:
    clock = ManualClock()
    done: list[float] = []
    with anyio.fail_after(2):
        async with anyio.create_task_group() as tg:
            tg.start_soon(_handoffs, clock, 10, done)
            tg.start_soon(_handoffs, clock, 30, done)
            await clock.advance(1.0)  # no sleep(0) here: advance waits for both chains
            assert done == [1.0, 1.0]


async def test_work_woken_at_one_deadline_settles_before_the_next_deadline() -> None:
    clock = ManualClock()
    seen: list[tuple[str, float]] = []

    async def chain_then_sleep() -> None:
        await clock.sleep(1.0)
        for _ in range(20):  # many yields between the wake-up and the next sleep
            await asyncio.sleep(0)
        await clock.sleep(1.0)  # registered at t=1: due at 2, before "late" at 2.5
        seen.append(("chained", clock.now()))

    async def late() -> None:
        await clock.sleep(2.5)
        seen.append(("late", clock.now()))

    with anyio.fail_after(2):
        async with anyio.create_task_group() as tg:
            tg.start_soon(chain_then_sleep)
            tg.start_soon(late)
            await clock.advance(3.0)
    assert seen == [("chained", 2.0), ("late", 2.5)]


async def test_advance_waits_for_actors_passing_mail_along_a_chain() -> None:
    clock = ManualClock()
    journal: list[str] = []
    with anyio.fail_after(2):
        async with ActorSystem("s", clock=clock) as system:
            relays = [Relay(journal) for _ in range(10)]
            refs = [system.spawn(r, f"r{i}") for i, r in enumerate(relays)]
            for relay, after in zip(relays, refs[1:], strict=False):
                relay.next = after

            async def kick_off() -> None:
                await clock.sleep(5.0)
                refs[0].tell(Hop(10))

            system.start_task(kick_off())
            await clock.advance(5.0)
            assert journal == [f"r{i}" for i in range(10)]


async def test_work_started_before_advancing_runs_before_time_moves() -> None:
    clock = ManualClock()
    woke: list[float] = []

    async def later() -> None:
        for _ in range(10):
            await asyncio.sleep(0)
        await clock.sleep(1.0)  # registered only after ten yields, at t=0
        woke.append(clock.now())

    with anyio.fail_after(2):
        task = asyncio.create_task(later())
        await clock.advance(1.0)
        assert woke == [1.0]
        await task


async def test_advance_refuses_a_busy_loop_and_negative_time() -> None:
    clock = ManualClock()

    async def spin() -> None:
        while True:  # noqa: ASYNC110 - the busy loop advance must refuse
            await asyncio.sleep(0)

    with anyio.fail_after(10):
        task = asyncio.create_task(spin())
        try:
            with pytest.raises(RuntimeError, match="never settled"):
                await clock.advance(1.0)
        finally:
            task.cancel()
        with pytest.raises(ValueError, match="advance by -1"):
            await clock.advance(-1)


async def test_sped_up_clock_sleeps_a_fraction_of_the_wall_time() -> None:
    clock = Clock(speedup=100_000)
    # 1000 clock seconds = 10 ms of wall; unsped they would be 1000 s, far past the
    # fail_after (a wall bound of 0.5 s here failed when the machine stalled the loop).
    with anyio.fail_after(30):
        start_wall, start_clock = time.monotonic(), clock.now()
        await clock.sleep(1000.0)
        wall = time.monotonic() - start_wall
    assert wall >= 0.008  # asyncio may fire a timer a hair early
    assert clock.now() - start_clock >= 999.0
    assert clock.to_wall(1000.0) == pytest.approx(0.01)
    assert clock.speedup == 100_000.0


async def test_clock_sleep_until_a_clock_deadline() -> None:
    clock = Clock(speedup=1000)
    with anyio.fail_after(30):
        deadline = clock.now() + 5.0  # 5 ms of wall
        await clock.sleep_until(deadline)
        assert clock.now() >= deadline - 0.01  # asyncio may fire a timer a hair early
    # In the past: no wait. Waiting for the distance instead would take 1000 s of wall,
    # which the fail_after sees (not a wall bound the machine's load could break).
    with anyio.fail_after(30):
        await clock.sleep_until(deadline - 1e6)


@pytest.mark.parametrize("speedup", [0, -1.0, float("nan")])
def test_clock_rejects_non_positive_speedups(speedup: float) -> None:
    with pytest.raises(ValueError, match="speedup must be > 0"):
        Clock(speedup)


def test_both_clocks_are_time_sources_and_systems_use_the_one_given() -> None:
    manual = ManualClock()
    assert isinstance(manual, TimeSource)
    assert isinstance(Clock(), TimeSource)
    assert ActorSystem("s", clock=manual).clock is manual
    assert isinstance(ActorSystem("s").clock, Clock)


async def test_autojump_skips_to_each_deadline_as_soon_as_all_wait() -> None:
    clock = ManualClock()
    woke: list[tuple[str, float]] = []

    async def sleeper(name: str, period: float, times: int) -> None:
        for _ in range(times):
            await clock.sleep(period)
            woke.append((name, clock.now()))

    with anyio.fail_after(5):
        async with clock.autojump(), anyio.create_task_group() as tg:
            tg.start_soon(sleeper, "slow", 1000.0, 3)
            tg.start_soon(sleeper, "fast", 400.0, 5)
    assert woke == [
        ("fast", 400.0),
        ("fast", 800.0),
        ("slow", 1000.0),
        ("fast", 1200.0),
        ("fast", 1600.0),
        ("slow", 2000.0),
        ("fast", 2000.0),
        ("slow", 3000.0),
    ]


async def test_autojump_waits_for_real_io_when_nobody_sleeps_on_the_clock() -> None:
    clock = ManualClock()
    with anyio.fail_after(5):
        async with clock.autojump():
            await asyncio.sleep(0.02)  # real time: the clock has nothing to jump to
            assert clock.now() == 0.0
            await clock.sleep(5.0)
            assert clock.now() == 5.0


async def test_autojump_stops_with_its_block() -> None:
    clock = ManualClock()
    async with clock.autojump():
        pass
    tasks = {t.get_name() for t in asyncio.all_tasks()}
    assert "autojump" not in tasks


# -- within: await something or give up on the clock -------------------------------------


async def test_within_returns_the_result_before_the_clock_runs_out() -> None:
    clock = ManualClock()
    with anyio.fail_after(2):
        async with clock.autojump():
            assert await within(clock, 5.0, _after(clock, 1.0, "done")) == "done"
            assert clock.now() == 1.0


async def test_within_gives_none_on_expiry_and_cancels_the_job() -> None:
    clock = ManualClock()
    job = asyncio.get_running_loop().create_future()
    ended: list[bool] = []

    async def waits() -> str:
        try:
            return str(await job)
        finally:
            ended.append(True)

    with anyio.fail_after(2):
        async with clock.autojump():
            assert await within(clock, 2.0, waits()) is None
            assert clock.now() == 2.0
        await asyncio.sleep(0)
    assert ended == [True]


async def test_within_propagates_the_job_error() -> None:
    async def fails() -> None:
        raise KeyError("boom")

    clock = ManualClock()
    with anyio.fail_after(2), pytest.raises(KeyError, match="boom"):
        await within(clock, 1.0, fails())


async def test_within_on_a_real_clock_bounds_the_wall_time() -> None:
    clock = Clock(speedup=100.0)  # 1 clock s = 10 ms
    never = asyncio.get_running_loop().create_future()
    with anyio.fail_after(30):
        # 1 ms of wall for the job against 1000 s for the limit: a loaded machine wakes
        # late, and a limit that expired in the same loop pass as the job would win
        assert await within(clock, 100_000.0, _after(clock, 0.1, 7)) == 7
        assert await within(clock, 1.0, never) is None
        # an error of the job's own, even a timeout, is not taken for expiry
        with pytest.raises(TimeoutError, match="own"):
            await within(clock, 1.0, _raise(TimeoutError("own")))


async def test_cancelling_the_waiter_cancels_the_job_and_the_timer() -> None:
    clock = ManualClock()
    ended: list[str] = []

    async def waits() -> None:
        try:
            await asyncio.get_running_loop().create_future()
        finally:
            ended.append("job")

    with anyio.fail_after(2):
        waiter = asyncio.ensure_future(within(clock, 5.0, waits()))
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert clock.pending == 1
        waiter.cancel()
        with pytest.raises(asyncio.CancelledError):
            await waiter
        await asyncio.sleep(0)
    assert ended == ["job"]
    assert clock.pending == 0


async def _after(clock: TimeSource, seconds: float, value: T) -> T:
    await clock.sleep(seconds)
    return value


async def _raise(exc: BaseException) -> None:
    raise exc


# -- ask timeouts on the virtual clock ------------------------------------------------------


class Never(Message):
    how: str


class Silent(Actor):
    """Never answers: its reply is deferred to a future nobody sets."""

    def __init__(self) -> None:
        super().__init__()
        self.kept: list[asyncio.Future[None]] = []

    @handler
    def on_never(self, msg: Never) -> asyncio.Future[None]:
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self.kept.append(fut)
        return fut


class SilentAsync(Actor):
    """Never answers: its async handler waits forever (the ask waits in its mailbox)."""

    @handler
    async def on_never(self, msg: Never) -> None:
        await asyncio.Event().wait()


def _burn_cpu(wall_s: float) -> None:
    """Block the event loop with work for ``wall_s`` seconds of wall time."""
    end = time.perf_counter() + wall_s
    while time.perf_counter() < end:
        pass


@pytest.mark.parametrize("path", ["deferred", "mailbox", "remote"])
async def test_an_unanswered_ask_times_out_at_its_virtual_instant_whatever_the_wall_does(
    path: str,
) -> None:
    clock = ManualClock(start=100.0)
    net = InProcessNetwork(MessageRegistry([Never]))
    errors: list[tuple[str, float]] = []
    with anyio.fail_after(5):
        async with (
            ActorSystem("a", transport=net.transport("a"), clock=clock) as a,
            ActorSystem("b", transport=net.transport("b"), clock=clock) as b,
        ):
            b.spawn(Silent(), "silent")
            b.spawn(SilentAsync(), "slow")
            where, how = {
                "deferred": (b.ref("silent"), "deferred"),
                "mailbox": (b.ref("slow"), "mailbox"),
                "remote": (a.ref("b/silent"), "deferred"),
            }[path]

            async def ask() -> None:
                try:
                    await where.ask(Never(how), timeout=0.05)  # clock seconds
                except AskTimeout as exc:
                    errors.append((str(exc), clock.now()))

            task = asyncio.create_task(ask())
            await clock.advance(0.0)
            _burn_cpu(0.2)  # four times the limit passes on the wall: it must not count
            await clock.advance(0.049)
            assert errors == []
            _burn_cpu(0.2)
            await clock.advance(0.001)
            assert len(errors) == 1
            assert errors[0][1] == pytest.approx(100.05)
            assert "within 0.05 s" in errors[0][0]
            await task


async def test_a_late_deferred_answer_after_a_virtual_timeout_is_dropped_quietly() -> None:
    clock = ManualClock()
    with anyio.fail_after(2):
        async with ActorSystem("s", clock=clock) as system:
            silent = Silent()
            ref = system.spawn(silent, "silent")
            task = asyncio.create_task(ref.ask(Never("deferred"), timeout=1.0))
            await clock.advance(1.0)
            with pytest.raises(AskTimeout):
                await task
            silent.kept[0].set_result(None)  # the handler's own future stays its own
            await clock.advance(0.0)


async def test_ask_timeouts_on_a_virtual_clock_are_clock_timers_not_loop_timers() -> None:
    clock = ManualClock()
    with anyio.fail_after(2):
        async with ActorSystem("s", clock=clock) as system:
            ref = system.spawn(SilentAsync(), "slow")
            task = asyncio.create_task(ref.ask(Never("mailbox"), timeout=30.0))
            await clock.advance(0.0)
            assert clock.next_deadline() == 30.0
            await clock.advance(30.0)
            with pytest.raises(AskTimeout):
                await task


async def test_a_clock_timer_fires_in_deadline_order_and_can_be_disarmed() -> None:
    clock = ManualClock()
    fired: list[tuple[str, float]] = []
    with anyio.fail_after(2):
        clock.call_later(2.0, lambda: fired.append(("b", clock.now())))
        clock.call_later(1.0, lambda: fired.append(("a", clock.now())))
        clock.call_later(1.5, fired.append, ("never", 0.0)).cancel()
        assert clock.pending == 2
        await clock.advance(5.0)
    assert fired == [("a", 1.0), ("b", 2.0)]
