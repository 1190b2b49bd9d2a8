"""Shared helpers for benchmarks: percentiles and result files."""

from __future__ import annotations

import asyncio
import json
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"

__all__ = ["RESULTS", "machine", "percentiles", "wait_until", "write_result"]


def percentiles(samples: Sequence[float]) -> dict[str, float]:
    """Median and p99 of ``samples`` (same unit as given)."""
    ordered = sorted(samples)
    if not ordered:
        raise ValueError("no samples")
    p99 = ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))]
    return {"p50": statistics.median(ordered), "p99": p99}


def machine() -> dict[str, Any]:
    import os

    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
    }


def write_result(name: str, data: dict[str, Any]) -> Path:
    """Write ``bench/results/NAME.json`` (with machine facts under ``_machine``)."""
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps({**data, "_machine": machine()}, indent=2, sort_keys=True) + "\n")
    return path


async def wait_until(cond: Callable[[], bool], limit: float, what: str) -> None:
    """Poll ``cond`` every 10 ms; a TimeoutError names ``what`` once ``limit`` s pass."""
    deadline = time.monotonic() + limit
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError(f"bench: {what} within {limit} s")
        await asyncio.sleep(0.01)
