"""Heartbeat traffic per robot as the team grows: all-to-all against the fanout.

Teams of 10, 25 and 50 robots run in one process on a virtual clock (in-process network,
every message encoded as over ZeroMQ). For 30 s of clock time each robot's membership
traffic (heartbeats, rosters, roster requests) is counted in messages and bytes per
second; then one robot is cut off and the time until every other robot has declared it
failed is measured, and any other failure is a false one. ``fanout = all`` is the
all-to-all baseline (every robot beats to every peer every period).
"""

from __future__ import annotations

import argparse
import asyncio
import time
from collections import Counter
from collections.abc import Callable
from contextlib import AsyncExitStack
from typing import Any

from btcap.actors import ManualClock
from btcap.bench.common import write_result
from btcap.team.core.members import TeamEvent
from btcap.team.messages import Heartbeat, Roster, RosterRequest
from btcap.team.runtime.agent import Agent, AgentConfig
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import BROADCAST, Codec, InProcessNetwork
from btcap.transports.codec import Envelope

__all__ = ["run"]

MEMBERSHIP = (Heartbeat, Roster, RosterRequest)
HEARTBEAT_S = 0.1
FAILURE_TIMEOUT_S = 1.0
WINDOW_S = 30.0


async def _team(size: int, fanout: int) -> dict[str, Any]:
    clock = ManualClock()
    reg = protocol_registry()
    net = InProcessNetwork(reg)
    codec = Codec(reg)
    msgs: Counter[str] = Counter()
    sizes: Counter[str] = Counter()
    window = {"on": False}
    cfg = AgentConfig(
        heartbeat_s=HEARTBEAT_S, failure_timeout_s=FAILURE_TIMEOUT_S, heartbeat_fanout=fanout
    )
    names = [f"r{i:02d}" for i in range(size)]
    failures: list[tuple[str, str, float]] = []

    def counting(name: str, send: Callable[[Envelope], None]) -> Callable[[Envelope], None]:
        def counted(env: Envelope) -> None:
            if window["on"] and isinstance(env.msg, MEMBERSHIP):
                copies = size - 1 if env.recipient.system == BROADCAST else 1
                msgs[name] += copies
                sizes[name] += copies * len(codec.encode(env))
            send(env)

        return counted

    def on_event(me: str) -> Callable[[TeamEvent, str], None]:
        def note(event: TeamEvent, robot: str) -> None:
            if event is TeamEvent.FAILED:
                failures.append((me, robot, clock.now()))

        return note

    async with clock.autojump(), AsyncExitStack() as stack:
        for name in names:
            transport = net.transport(name)
            transport.send = counting(name, transport.send)  # type: ignore[method-assign,assignment]
            agent = Agent(name, transport=transport, clock=clock, config=cfg)
            await stack.enter_async_context(agent)
            agent.team.subscribe(on_event(name))
        await clock.sleep(5.0)  # everybody has met everybody
        window["on"] = True
        await clock.sleep(WINDOW_S)
        window["on"] = False
        victim = names[-1]
        net.isolate(victim)
        cut = clock.now()
        others = set(names) - {victim}
        while {me for me, robot, _ in failures if robot == victim} < others:
            if clock.now() - cut > 10 * FAILURE_TIMEOUT_S:
                break
            await clock.sleep(HEARTBEAT_S / 2)
        seen = [t for me, robot, t in failures if robot == victim and me != victim]
    return {
        "msgs_per_s": round(sum(msgs.values()) / size / WINDOW_S, 1),
        "kbytes_per_s": round(sum(sizes.values()) / size / WINDOW_S / 1000, 2),
        "detect_s": round(max(seen) - cut, 2) if len(seen) == size - 1 else None,
        "false_failures": sum(1 for me, robot, _ in failures if victim not in (me, robot)),
    }


def run(quick: bool = False) -> dict[str, Any]:
    sizes = (10, 25) if quick else (10, 25, 50)
    out: dict[str, Any] = {"heartbeat_s": HEARTBEAT_S, "failure_timeout_s": FAILURE_TIMEOUT_S}
    t0 = time.perf_counter()
    print(
        f"membership traffic per robot (heartbeat {HEARTBEAT_S} s, timeout {FAILURE_TIMEOUT_S} s)"
    )
    print(f"{'robots':>6} {'fanout':>6} {'msgs/s':>8} {'kB/s':>7} {'detect s':>8} {'false':>5}")
    for size in sizes:
        for fanout in (size, 8):
            row = asyncio.run(_team(size, fanout))
            label = "all" if fanout >= size - 1 else str(fanout)
            out[f"{size}/{label}"] = row
            print(
                f"{size:>6} {label:>6} {row['msgs_per_s']:>8} {row['kbytes_per_s']:>7} "
                f"{row['detect_s']:>8} {row['false_failures']:>5}"
            )
    out["seconds"] = round(time.perf_counter() - t0, 1)
    write_result("membership", out)
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--quick", action="store_true")
    run(quick=p.parse_args().quick)
