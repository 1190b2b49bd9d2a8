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
