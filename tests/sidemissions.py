"""Fast missions computed ahead on one worker process while the suite goes on.

A ``run_fast`` mission is deterministic (its result does not depend on the process, the
hash seed or the machine's load: tests/sim/running/test_mission_run.py and
tests/sim/running/test_cli_run.py check it), so a module whose tests read many such runs
may have them computed on the machine's second core while its own process runs the
others. Only wall time changes: the result is the one the test process would compute
(the same ``run_fast``, the same ``BTCAP_DEBUG`` from the environment).
"""

from __future__ import annotations

import asyncio
import multiprocessing
from collections.abc import Hashable, Iterable
from concurrent.futures import Future, ProcessPoolExecutor

from btcap.sim.mission.scenario import Scenario
from btcap.sim.running.metrics import MissionResult

__all__ = ["SideMissions", "run_one"]


def run_one(scenario: Scenario) -> MissionResult:
    """One fast mission, in the worker (importable there: ``tests`` is on its path)."""
    from btcap.sim.running.runner import run_fast

    return asyncio.run(run_fast(scenario))


class SideMissions:
    """Scenarios handed to one spawned worker (no fork of the suite's threads), in the
    order given; :meth:`take` hands a result over once, or ``None`` if it was never
    asked for here (the caller then runs the mission itself)."""

    def __init__(self, runs: Iterable[tuple[Hashable, Scenario]]) -> None:
        self._futures: dict[Hashable, Future[MissionResult]] = {}
        runs = list(runs)
        self._pool = (
            ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
            if runs
            else None
        )
        for key, scenario in runs:
            assert self._pool is not None
            self._futures[key] = self._pool.submit(run_one, scenario)

    async def take(self, key: Hashable) -> MissionResult | None:
        future = self._futures.pop(key, None)
        return None if future is None else await asyncio.wrap_future(future)

    def close(self) -> None:
        """Cancel what has not started and wait for the worker to end."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
