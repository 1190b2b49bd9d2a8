"""How long a mission waits per capability: the wall time from a mission tree starting a
capability node to the node's result, against the mission tree's tick period.

An origin robot with no implementation runs missions of ``STEPS`` Echo capabilities in a
Sequence (each told to stop at once: its run succeeds on its first tick) on an executor
robot, in-process, on the wall clock (speed-up 1), the mission tree ticked by
``Tree.run`` at ``MISSION_HZ``; the executor ticks its tree at its own rate (the default
``tick_hz``). Every step is an auction, an award, the inputs out, the run's tick on the
executor and its result back: each a message the mission tree either acts on at once (a
nudge) or at its next tick. Reported: the median step in milliseconds and divided by the
mission's tick period (the peer: without nudges a step waits for about 2-3 periods).
``python -m btcap.bench mission_step``; runs as a script too (``python
bench/speed/mission_step.py``), so the same file measures an older btcap.
"""

from __future__ import annotations

import asyncio
import os
import statistics
import time
from typing import Any

from btcap import Sequence
from btcap.team.demo import ECHO, implementations
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import InProcessNetwork

__all__ = ["run"]

MISSION_HZ = 10.0
STEPS = 5


async def _measure(missions: int) -> list[float]:
    net = InProcessNetwork(protocol_registry())
    steps: list[float] = []
    async with (
        Agent("origin", transport=net.transport("origin")) as origin,
        Agent("x", transport=net.transport("x"), implementations=implementations("x")),
    ):
        deadline = time.monotonic() + 30.0
        while "x" not in origin.repository.providers(ECHO.identity) & origin.team.alive():
            if time.monotonic() > deadline:
                raise TimeoutError("bench mission_step: the executor did not join")
            await asyncio.sleep(0.05)
        for m in range(missions + 1):  # the first warms up
            nodes = [
                ECHO.node_type()(f"echo{i}", inputs={"value": i, "stop": True})
                for i in range(STEPS)
            ]
            t0 = time.perf_counter()
            await origin.run_mission(Sequence(f"m{m}", children=nodes), rate_hz=MISSION_HZ)
            if m:
                steps.append((time.perf_counter() - t0) / STEPS)
    return steps


def run(quick: bool = False) -> dict[str, Any]:
    """Measure, print, and (as part of btcap.bench) write ``bench/results/mission_step.json``."""
    load_before = os.getloadavg()[0]
    steps = asyncio.run(_measure(3 if quick else 10))
    period = 1.0 / MISSION_HZ
    median = statistics.median(steps)
    data = {
        "mission_hz": MISSION_HZ,
        "steps_per_mission": STEPS,
        "step_ms": {"median": median * 1e3, "min": min(steps) * 1e3, "max": max(steps) * 1e3},
        "step_per_period": median / period,
        "load_average": [load_before, os.getloadavg()[0]],
    }
    print(
        f"mission step: median {median * 1e3:.1f} ms = {median / period:.2f} x the mission's "
        f"tick period ({period * 1e3:.0f} ms); load {data['load_average']}"
    )
    if __name__ != "__main__":
        from btcap.bench.common import write_result

        write_result("mission_step", data)
    return data


if __name__ == "__main__":
    run()
