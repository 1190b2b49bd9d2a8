"""Remote capability tick round trips and fail-over times for :mod:`bench.speed.auction`.

- **remote_tick_ms**: the origin's ``tree.tick()`` sends inputs (seq n) to an executor in
  another process; timed until ``execution.acked >= n`` (the executor's status for them
  arrived back).
- **failover_s**: the executing robot's process is SIGKILLed; timed until the capability
  runs again on another robot (its execution is set, on another robot, and running), at
  speed-up 1 with the default :class:`~btcap.team.runtime.agent.AgentConfig`.
"""

from __future__ import annotations

import asyncio
import gc
import time
from typing import Any

from btcap import ReactiveSequence as SequenceNode
from btcap.bench.common import wait_until
from btcap.bt.state import State
from btcap.team.capabilities.proxies import RemoteExecution
from btcap.team.demo import ECHO
from btcap.team.deployment.launch import AgentSpec, spawn_agents
from btcap.team.runtime.agent import Agent
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import ZmqTransport

__all__ = ["bench_remote"]

MISSION_TICK_HZ = 100.0  # how often the origin ticks its tree while waiting for fail-over
_LOCAL = "127.0.0.1"


def _executor_spec(i: int) -> AgentSpec:
    return AgentSpec(
        robot=f"x{i}", factory="btcap.team.demo:implementations", factory_args={"cost": 1.0 + i}
    )


async def bench_remote(
    warmup: int, ticks: int, failovers: int
) -> tuple[list[float], list[float], dict[str, Any]]:
    """Remote tick round trips (ms) on the first executor, then fail-over times (s)."""
    procs = spawn_agents([_executor_spec(i) for i in range(failovers + 1)], timeout=60.0)
    by_robot = {p.robot: p for p in procs}
    try:
        reg = protocol_registry()
        peers = {p.robot: p.endpoint for p in procs}
        transport = ZmqTransport("origin", f"tcp://{_LOCAL}:*", reg, peers=peers)
        async with Agent("origin", transport=transport, registry=reg) as origin:
            await wait_until(
                lambda: len(origin.repository.providers(ECHO.identity)) == len(procs),
                30.0,
                "executors joined",
            )
            node = ECHO.node_type()("echo", inputs={"value": 0})
            tree = origin.mission(SequenceNode("root", children=[node]))
            period = 1.0 / MISSION_TICK_HZ

            async def running_on_new(old: str | None, limit: float) -> None:
                deadline = time.monotonic() + limit
                while True:
                    tree.tick()
                    ex = node.execution
                    if ex is not None and ex.robot != old and node.state is State.RUNNING:
                        return
                    if time.monotonic() > deadline:
                        raise TimeoutError(f"bench auction: not re-assigned in {limit} s")
                    await asyncio.sleep(period)

            await running_on_new(None, 10.0)
            rtt = await _remote_ticks(node, tree, warmup, ticks)
            failover: list[float] = []
            for _ in range(failovers):
                victim = node.execution
                assert victim is not None
                proc = by_robot[victim.robot]
                # Let the new executor settle into its lease before failing it.
                await asyncio.sleep(0.3)
                t0 = time.perf_counter()
                proc.kill()
                await running_on_new(victim.robot, 10.0)
                failover.append(time.perf_counter() - t0)
            node.set_input("stop", True)
            await wait_until(lambda: tree.tick() is State.SUCCEEDED, 5.0, "echo finished")
            info = {
                "assignments": list(node.assignments),
                "mission_tick_hz": MISSION_TICK_HZ,
                "lost": origin.mission_control.stats.lost,
            }
            await tree.shutdown()
            return rtt, failover, info
    finally:
        for p in procs:
            p.stop()


async def _remote_ticks(node: Any, tree: Any, warmup: int, count: int) -> list[float]:
    ex = node.execution
    if not isinstance(ex, RemoteExecution):
        raise RuntimeError("bench auction: expected a remote execution")
    samples: list[float] = []
    clock = time.perf_counter_ns
    for i in range(warmup + count):
        if i == warmup:
            gc.collect()
        node.set_input("value", i)
        t0 = clock()
        tree.tick()
        n = ex.tracked.seq
        # Spin: the status comes back within a fraction of a millisecond.
        while ex.tracked.acked < n:  # noqa: ASYNC110 - a spin is the measurement
            await asyncio.sleep(0)
        if i >= warmup:
            samples.append((clock() - t0) / 1e6)
    if node.outputs.get("robot") != ex.robot:
        raise RuntimeError("bench auction: outputs did not come back from the executor")
    return samples
