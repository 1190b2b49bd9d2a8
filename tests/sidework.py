"""Deterministic work computed ahead on one worker process while the suite goes on.

A fast mission (``run_fast``) or a fault-simulator seed (``run_plan``) is deterministic:
its result does not depend on the process, the hash seed or the machine's load
(tests/sim/running/test_mission_run.py, tests/sim/running/test_cli_run.py and
tests/sim/faults/test_simtest.py check it). A module whose tests read many such results
may have some computed on the machine's second core while its own process computes the
others. Only wall time changes: each result is the one this process would compute (the
same function, the same environment, ``BTCAP_DEBUG`` included), and a warning fails it
there as here (the worker takes the warning filters in force when it starts).
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
import re
import warnings
from collections.abc import Callable, Hashable
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any

from btcap.sim.mission.scenario import Scenario
from btcap.sim.running.metrics import MissionResult

__all__ = ["AHEAD", "SideWork", "run_mission"]


def run_mission(scenario: Scenario) -> MissionResult:
    """One fast mission, in the worker (importable there: ``tests`` is on its path)."""
    from btcap.sim.running.runner import run_fast

    return asyncio.run(run_fast(scenario))


Filter = tuple[str, str, type[Warning], str, int]  # warnings.filterwarnings' arguments


def _filters() -> list[Filter]:
    """The warning filters in force here (in a test: the suite's, warnings as errors)."""

    def text(pattern: re.Pattern[str] | str | None) -> str:
        return getattr(pattern, "pattern", pattern) or ""

    return [
        (action, text(message), category, text(module), lineno)
        for action, message, category, module, lineno in warnings.filters
    ]


def _same_filters(filters: list[Filter]) -> None:
    """The worker's initializer: the test process's filters, so a warning that would fail
    a test made here fails it when made on the worker."""
    warnings.resetwarnings()
    for action, message, category, module, lineno in reversed(filters):
        warnings.filterwarnings(action, message, category, module, lineno)  # type: ignore[arg-type]


class SideWork:
    """Calls handed to one spawned worker (no fork of the suite's threads), run in the
    order submitted; :meth:`take` hands each result's future over once, or ``None`` for
    a key never submitted (the caller then does the work itself)."""

    def __init__(self) -> None:
        self._pool: ProcessPoolExecutor | None = None
        self._futures: dict[Hashable, Future[Any]] = {}
        self._holders: set[str] = set()

    def submit(self, key: Hashable, fn: Callable[..., Any], *args: Any) -> None:
        """Queue ``fn(*args)`` on the worker; not under pytest-xdist, whose workers have
        the cores already (and each would make every run its module lists)."""
        if os.environ.get("PYTEST_XDIST_WORKER"):
            return
        if self._pool is None:
            spawn = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(
                max_workers=1, mp_context=spawn, initializer=_same_filters, initargs=(_filters(),)
            )
        self._futures[key] = self._pool.submit(fn, *args)

    def take(self, key: Hashable, *, steal: bool = False) -> Future[Any] | None:
        """``steal``: a call the worker has not started is cancelled and ``None`` given
        (the caller makes it now rather than wait for its turn)."""
        future = self._futures.pop(key, None)
        if steal and future is not None and future.cancel():
            return None
        return future

    def hold(self, holder: str) -> None:
        """``holder`` (a test module) takes work from the worker until it releases it."""
        self._holders.add(holder)

    def release(self, holder: str) -> None:
        """``holder`` is done: once nobody holds it, the worker ends (what is left is
        cancelled), so no later test sees it."""
        self._holders.discard(holder)
        if not self._holders:
            self.close()

    def pids(self) -> set[int]:
        """The worker's process ids (none before the first call or after :meth:`close`)."""
        processes = getattr(self._pool, "_processes", None) or {}
        return set(processes)

    def close(self) -> None:
        """Cancel what has not started and wait for the worker to end."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._futures.clear()


#: The worker test modules share: each queues the work its selected tests will read once
#: the suite is collected (``start_ahead``, tests/conftest.py), in the suite's order, so
#: it is made on the second core while the tests before those modules run here; each
#: module releases it when it ends (or the session does).
AHEAD = SideWork()
