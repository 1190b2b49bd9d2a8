"""A monitor following a virtual clock batches on that clock, so a recording of a
deterministic run depends on the run alone, never on how fast the machine computed it."""

from __future__ import annotations

import asyncio
from pathlib import Path

import anyio
import pytest

from btcap import Monitor
from btcap.actors import Clock, ManualClock
from btcap.monitor import read_record


async def _shown(monitor: Monitor, robot: str) -> None:
    """Until ``robot`` is in the monitor's snapshot (the caller's fail_after bounds it;
    a fixed sleep would depend on the machine's load)."""
    while robot not in monitor.snapshot()["robots"]:  # noqa: ASYNC110 (no event to wait on)
        await asyncio.sleep(0.01)


async def test_batches_fall_on_the_virtual_clock(tmp_path: Path) -> None:
    clock = ManualClock()
    with anyio.fail_after(10):
        async with Monitor(port=None, record=tmp_path / "r.jsonl") as monitor:
            monitor.follow(clock, every_s=1.0)
            monitor.emit({"t": 0.0, "k": "robot", "robot": "a"})
            await asyncio.sleep(0.15)  # wall time passes: no batch goes out
            assert "a" not in monitor.snapshot()["robots"]
            await clock.advance(1.0)
            assert "a" in monitor.snapshot()["robots"]
            monitor.emit({"t": 1.2, "k": "robot", "robot": "b"})
            monitor.detach()  # back on wall time (and what is pending goes out)
            assert "b" in monitor.snapshot()["robots"]
            monitor.emit({"t": 1.3, "k": "robot", "robot": "c"})
            await _shown(monitor, "c")  # by the wall-time batches again
    robots = [e["robot"] for e in read_record(tmp_path / "r.jsonl") if e["k"] == "robot"]
    assert robots == ["a", "b", "c"]


async def test_a_real_clock_leaves_the_wall_pace() -> None:
    with anyio.fail_after(10):
        async with Monitor(port=None) as monitor:
            monitor.follow(Clock(1000.0))
            monitor.emit({"t": 0.0, "k": "robot", "robot": "a"})
            await _shown(monitor, "a")  # no clock advance needed: wall-time batches


async def test_follow_needs_a_started_monitor_and_a_period() -> None:
    monitor = Monitor(port=None)
    with pytest.raises(RuntimeError, match="start the monitor"):
        monitor.follow(ManualClock())
    with pytest.raises(ValueError, match="every_s"):
        monitor.follow(ManualClock(), every_s=0)


async def test_batches_on_a_virtual_clock_cost_it_no_wake_up(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A recording must not slow a ``--fast`` run down: a batch is a timer of the clock,
    and the clock lets the loop settle only after wake-ups that made something ready, so
    a followed clock settles as often as one nobody watches (issue 32's budget)."""
    import btcap.actors.clock as clock_module

    settles = [0]
    settle = clock_module._settle

    async def counted() -> None:
        settles[0] += 1
        await settle()

    monkeypatch.setattr(clock_module, "_settle", counted)

    async def run(monitor: Monitor | None) -> int:
        clock = ManualClock()
        if monitor is not None:
            monitor.follow(clock, every_s=0.5)
        await asyncio.sleep(0)  # the batches' timer is armed as a flusher task would start

        async def steps() -> None:  # a simulator stepping every 0.5 s
            deadline = 0.0
            while True:
                deadline += 0.5
                await clock.sleep_until(deadline)

        task = asyncio.get_running_loop().create_task(steps())
        settles[0] = 0
        await clock.advance(10.0)
        task.cancel()
        return settles[0]

    with anyio.fail_after(10):
        alone = await run(None)
        async with Monitor(port=None, record=tmp_path / "r.jsonl") as monitor:
            monitor.emit({"t": 0.0, "k": "robot", "robot": "a"})
            followed = await run(monitor)
            assert "a" in monitor.snapshot()["robots"]  # the batches fell all the same
    assert followed == alone
