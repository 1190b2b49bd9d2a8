"""CPU time a benchmark's rounds cost, in this process and in its child processes.

On a small shared machine CPU per round says more than wall time, and only the work the
rounds add counts: what the processes burn idle (heartbeats, host trees) is measured first
and taken off, and waits between bursts of rounds can be left out (:meth:`CpuMeter.pause`).
"""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Sequence

__all__ = ["CpuMeter", "cpu_of"]

_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def cpu_of(pid: int) -> float:
    """CPU seconds (user + system, every thread) a child process used so far (Linux)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / _TICK


class CpuMeter:
    """CPU time per round of this process and of child processes, minus what they burn
    idle (heartbeats, host trees), so the figure is what the rounds themselves cost."""

    def __init__(self, pids: Sequence[int] = ()) -> None:
        self.pids = list(pids)
        self.idle_self = 0.0
        self.idle_children = 0.0
        self._spent = (0.0, 0.0, 0.0)
        self._start: tuple[float, float, float] | None = None

    def _read(self) -> tuple[float, float, float]:
        kids = sum(cpu_of(pid) for pid in self.pids)
        return time.perf_counter(), time.process_time(), kids

    async def calibrate(self, seconds: float) -> None:
        w0, s0, c0 = self._read()
        await asyncio.sleep(seconds)
        w1, s1, c1 = self._read()
        self.idle_self = (s1 - s0) / (w1 - w0)
        self.idle_children = (c1 - c0) / (w1 - w0)

    def start(self) -> None:
        """Count from now, afresh."""
        self._spent = (0.0, 0.0, 0.0)
        self._start = self._read()

    def pause(self) -> None:
        """Stop counting (waits between the rounds are not theirs) until :meth:`resume`."""
        if self._start is not None:
            (w0, s0, c0), (w1, s1, c1) = self._start, self._read()
            wall, own, kids = self._spent
            self._spent = (wall + w1 - w0, own + s1 - s0, kids + c1 - c0)
            self._start = None

    def resume(self) -> None:
        """Count again after :meth:`pause`."""
        if self._start is None:
            self._start = self._read()

    def per_round_ms(self, rounds: int) -> dict[str, float]:
        self.pause()
        wall, own, kids = self._spent
        out = {"this_process": (own - self.idle_self * wall) / rounds * 1e3}
        if self.pids:
            out["bidder_processes"] = (kids - self.idle_children * wall) / rounds * 1e3
        return out
