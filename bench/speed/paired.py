"""A/B verdicts that hold on a shared machine: paired runs and instruction counts.

Two conditions run in turns (none, mcap, none, mcap ...); a run's CPU time swings with
what else the machine does (±10 % here), but the two runs of a pair share most of it. So
the statistic is the median of the per-pair ratios, with a percentile bootstrap
confidence interval (seeded: the same runs give the same interval). Steadier still, if
``valgrind`` is installed: the instructions one run of each executes, which no load
changes (``perf stat`` counts them faster, but a virtual machine often has no counters).
"""

from __future__ import annotations

import os
import re
import shutil
import statistics
import subprocess
from collections.abc import Sequence

import numpy as np
from scipy.stats import bootstrap

__all__ = ["instructions", "median_ci", "pair_ratios"]

#: How sure the interval is, and how many resamples it is read from.
CONFIDENCE = 0.95
RESAMPLES = 9999

_REFS = re.compile(rb"I\s+refs:\s+([\d,]+)")


def pair_ratios(runs: Sequence[float], base: Sequence[float]) -> list[float]:
    """``runs[i] / base[i]``: each run over the base run of its own turn."""
    if len(runs) != len(base):
        raise ValueError(f"{len(runs)} runs against {len(base)} base runs: expected pairs")
    return [r / b for r, b in zip(runs, base, strict=True)]


def median_ci(values: Sequence[float], *, seed: int = 0) -> tuple[float, float, float]:
    """(median, low, high): the median of ``values`` and its :data:`CONFIDENCE` percentile
    bootstrap interval; fewer than three values give no interval (NaN, NaN)."""
    med = statistics.median(values)
    if len(values) < 3 or len(set(values)) == 1:
        return med, float("nan"), float("nan")
    res = bootstrap(
        (np.asarray(values, dtype=float),),
        np.median,
        confidence_level=CONFIDENCE,
        n_resamples=RESAMPLES,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    ci = res.confidence_interval
    return med, float(ci.low), float(ci.high)


def instructions(argv: Sequence[str]) -> int | None:
    """Instructions the command ``argv`` executes under valgrind (cachegrind, no cache
    simulation: about 30 times slower than the command), or None without valgrind.
    Python's hash seed is fixed, so a deterministic command counts the same each time."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        return None
    cmd = [valgrind, "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null"]
    env = {**os.environ, "PYTHONHASHSEED": "0"}
    done = subprocess.run([*cmd, *argv], capture_output=True, env=env, check=False)
    found = _REFS.search(done.stderr)
    if done.returncode != 0 or found is None:
        tail = done.stderr.decode(errors="replace").strip().splitlines()[-3:]
        raise RuntimeError(f"valgrind {' '.join(argv)}: exit {done.returncode}: {tail}")
    return int(found.group(1).replace(b",", b""))
