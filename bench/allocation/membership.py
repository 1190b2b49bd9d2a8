"""Failure detection with the defaults as the team grows: false failures, detection time,
traffic per robot.

Two ways, both on a virtual clock with 1 % of membership messages lost (seeded):

- ``core``: the real sans-IO protocol (:class:`~btcap.team.core.swim.Swim`) of every robot
  over the seeded discrete-event network of :mod:`btcap.sim.faults.swimnet` (latency 1-5 ms),
  for teams of 10, 50, 200 and 500 robots and 30 simulated minutes each: simulating 500
  full agents that long would take hours, and the core is where every decision is made.
- ``agents``: full :class:`~btcap.team.runtime.agent.Agent` objects (membership actor,
  repository, mission control, host tree) over the in-process network, every message
  encoded as over ZeroMQ, for teams of 10 and 50 and 2 simulated minutes.

In each, after the window one robot is killed (cut off) and the time until every other
robot has declared it failed is compared with the stated bound
(:meth:`~btcap.team.core.swim.SwimParams.detection_bound_s`); any other failure is a false
one. Traffic is counted over the window, per robot and second of clock time (sent
membership messages, bytes with their envelope).
"""

from __future__ import annotations

import argparse
import asyncio
import random
import time
from collections.abc import Callable
from contextlib import AsyncExitStack
from typing import Any

from btcap.actors import ManualClock
from btcap.bench.common import write_result
from btcap.sim.faults.swimnet import SwimNet
from btcap.team.core.members import TeamEvent
from btcap.team.core.swim import SwimParams
from btcap.team.messages import Goodbye, Heartbeat, ProbeRequest, Roster, RosterRequest, Vouch
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import BROADCAST, Codec, InProcessNetwork
from btcap.transports.codec import Envelope

__all__ = ["agent_team", "core_team", "run"]

MEMBERSHIP = (Heartbeat, Roster, RosterRequest, ProbeRequest, Vouch, Goodbye)
LOSS = 0.01
DEFAULTS = AgentConfig()
PARAMS = SwimParams(
    DEFAULTS.heartbeat_s, DEFAULTS.failure_timeout_s, news=DEFAULTS.heartbeat_fanout
)


def core_team(size: int, window_s: float, seed: int = 1) -> dict[str, Any]:
    names = [f"r{i:03d}" for i in range(size)]
    net = SwimNet(names, PARAMS, seed=seed, loss=LOSS)
    net.run_until(window_s)
    sent = sum(r.sent for r in net.robots.values())
    nbytes = sum(r.bytes for r in net.robots.values())
    net.counting = False
    victim = names[size // 2]
    net.kill(victim)
    bound = PARAMS.detection_bound_s(size)
    net.run_until(window_s + 3 * bound)
    seen = {e.observer: e.at - window_s for e in net.failures() if e.robot == victim}
    false = sum(1 for e in net.failures() if e.robot != victim)  # in the window or after
    return {
        "msgs_per_s": round(sent / size / window_s, 2),
        "bytes_per_s": round(nbytes / size / window_s),
        "false_failures": false,
        "detect_s": round(max(seen.values()), 2) if len(seen) == size - 1 else None,
        "detect_median_s": round(sorted(seen.values())[len(seen) // 2], 2) if seen else None,
        "bound_s": round(bound, 2),
    }


async def agent_team(size: int, window_s: float, seed: int = 1) -> dict[str, Any]:
    clock = ManualClock()
    reg = protocol_registry()
    net = InProcessNetwork(reg)
    codec = Codec(reg)
    rng = random.Random(f"loss {seed}")
    msgs = {"n": 0, "bytes": 0}
    window = {"on": False}
    names = [f"r{i:02d}" for i in range(size)]
    failures: list[tuple[str, str, float]] = []

    def lossy(send: Callable[[Envelope], None]) -> Callable[[Envelope], None]:
        def sent(env: Envelope) -> None:
            if isinstance(env.msg, MEMBERSHIP):
                copies = size - 1 if env.recipient.system == BROADCAST else 1
                if window["on"]:
                    msgs["n"] += copies
                    msgs["bytes"] += copies * len(codec.encode(env))
                if rng.random() < LOSS:
                    return
            send(env)

        return sent

    def on_event(me: str) -> Callable[[TeamEvent, str], None]:
        def note(event: TeamEvent, robot: str) -> None:
            if event is TeamEvent.FAILED:
                failures.append((me, robot, clock.now()))

        return note

    async with clock.autojump(), AsyncExitStack() as stack:
        for name in names:
            transport = net.transport(name)
            transport.send = lossy(transport.send)  # type: ignore[method-assign,assignment]
            agent = Agent(name, transport=transport, clock=clock, config=DEFAULTS)
            await stack.enter_async_context(agent)
            agent.team.subscribe(on_event(name))
        await clock.sleep(5.0)  # everybody has met everybody
        joined = len(failures)
        window["on"] = True
        await clock.sleep(window_s)
        window["on"] = False
        victim = names[-1]
        net.isolate(victim)
        cut = clock.now()
        others = set(names) - {victim}
        bound = PARAMS.detection_bound_s(size)
        while {me for me, robot, _ in failures if robot == victim} < others:
            if clock.now() - cut > 3 * bound:
                break
            await clock.sleep(DEFAULTS.heartbeat_s)
        seen = [t for me, robot, t in failures if robot == victim and me != victim]
    return {
        "msgs_per_s": round(msgs["n"] / size / window_s, 2),
        "bytes_per_s": round(msgs["bytes"] / size / window_s),
        "false_failures": sum(1 for me, robot, _ in failures if victim not in (me, robot)),
        "false_while_joining": joined,
        "detect_s": round(max(seen) - cut, 2) if len(seen) == size - 1 else None,
        "bound_s": round(bound, 2),
    }


def _print(kind: str, size: int, window_s: float, row: dict[str, Any]) -> None:
    print(
        f"{kind:>6} {size:>6} {window_s:>7.0f} {row['msgs_per_s']:>7} {row['bytes_per_s']:>7} "
        f"{row['false_failures']:>5} {row['detect_s']!s:>8} {row['bound_s']:>7}"
    )


def run(quick: bool = False) -> dict[str, Any]:
    core = (
        ((10, 60.0), (50, 60.0))
        if quick
        else ((10, 1800.0), (50, 1800.0), (200, 1800.0), (500, 1800.0))
    )
    agents = ((10, 20.0),) if quick else ((10, 120.0), (50, 120.0))
    out: dict[str, Any] = {
        "heartbeat_s": DEFAULTS.heartbeat_s,
        "failure_timeout_s": DEFAULTS.failure_timeout_s,
        "heartbeat_fanout": DEFAULTS.heartbeat_fanout,
        "loss": LOSS,
    }
    t0 = time.perf_counter()
    print(
        f"membership with the defaults (period {DEFAULTS.heartbeat_s} s, suspicion floor "
        f"{DEFAULTS.failure_timeout_s} s), {LOSS:.0%} of messages lost"
    )
    print(
        f"{'':>6} {'robots':>6} {'window':>7} {'msgs/s':>7} {'B/s':>7} {'false':>5} "
        f"{'detect s':>8} {'bound s':>7}"
    )
    for size, window_s in core:
        row = core_team(size, window_s)
        out[f"core/{size}"] = {"window_s": window_s, **row}
        _print("core", size, window_s, row)
    for size, window_s in agents:
        row = asyncio.run(agent_team(size, window_s))
        out[f"agents/{size}"] = {"window_s": window_s, **row}
        _print("agents", size, window_s, row)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    write_result("membership", out)
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    run(quick=p.parse_args().quick)
