"""ROS 2 bridge benchmark: a goal's round trip through btcap's RosAction against rclpy's
own ActionClient on the same server in the same run, and tick jitter with and without a
1 kHz feedback stream.

Needs ROS 2 (`make ros`) and runs in a private network namespace: ``make bench-ros``
(python -m btcap.bench ros under tests/rosnet.py with .venv-ros). The server
(``bench/ros/server.py``) runs in a process of its own; both clients run in this one,
each with its own DDS participant and executor thread, and take turns round by round so
load elsewhere on the machine lands on both alike.

- Round trip: goal sent -> result in hand, on an action that succeeds at once. rclpy's
  client waits on a threading.Event set by its result callback (its usual shape);
  btcap's node is ticked by the event loop when the bridge says a goal answered
  (``RosBridge.wake_on``), as a runner ticking on news would, and also polled at 1 kHz.
- The same inside a tree run as an agent runs its trees (``Tree.run`` at 10 Hz, the
  agents' default tick): with the news nudging the tree (the default), and without
  (``RosBridge.nudges = False``: the result waits for the next periodic tick).
- Jitter: a tree ticked at 200 Hz (drift-free) for a few seconds; how late each tick
  is, with the tree idle and with a RosAction whose server streams feedback at 1 kHz.
"""

from __future__ import annotations

import asyncio
import os
import random
import subprocess
import sys
import threading
import time
from typing import Any

from btcap.bench.common import percentiles, write_result
from btcap.bt.leaves import AlwaysRunning
from btcap.bt.node import Node
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros.action import RosAction
from btcap.ros.base import give
from btcap.ros.client import RosBridge
from btcap.ros.loader import load
from btcap.team.rossettings import RosSettings

__all__ = ["run"]

FIB = "test_msgs/action/Fibonacci"
NAMESPACE = "/bench"
#: The agents' default tick rate (``timing.tick_hz``).
AGENT_HZ = 10.0
_RUNNING = State.RUNNING


def _server(domain: int) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "btcap.bench.ros.server", NAMESPACE],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
    )
    assert proc.stdout is not None
    if proc.stdout.readline().strip() != "ready":
        proc.kill()
        raise RuntimeError("bench: the ROS server did not start")
    return proc


class _RclpyClient:
    """rclpy's ActionClient on a node and executor thread of its own: the peer."""

    def __init__(self, domain: int) -> None:
        rclpy = self.rclpy = load()
        from rclpy.action import ActionClient
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from test_msgs.action import Fibonacci

        self.goal = Fibonacci.Goal(order=1)
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("peer", namespace=NAMESPACE, context=self.context)
        self.client = ActionClient(self.node, Fibonacci, "instant")
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        if not self.client.wait_for_server(timeout_sec=10.0):
            raise RuntimeError("bench: rclpy's client found no server")

    def round_trip(self) -> float:
        done = threading.Event()

        def on_goal(future: Any) -> None:
            future.result().get_result_async().add_done_callback(lambda _: done.set())

        t0 = time.perf_counter()
        self.client.send_goal_async(self.goal).add_done_callback(on_goal)
        if not done.wait(10.0):
            raise RuntimeError("bench: rclpy's goal did not finish")
        return time.perf_counter() - t0

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.thread.join(timeout=5.0)
        self.client.destroy()
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


async def _node_round_trip(tree: Tree, woken: asyncio.Event | None) -> float:
    """One goal through the RosAction at ``tree``'s root: ticked on wake-ups, or every ms."""
    t0 = time.perf_counter()
    state = tree.tick()
    while state is _RUNNING:
        if woken is not None:
            await woken.wait()
            woken.clear()
        else:
            await asyncio.sleep(0.001)
        state = tree.tick()
    if state is not State.SUCCEEDED:
        raise RuntimeError(f"bench: the goal ended {state.value}: {tree.root.error}")
    return time.perf_counter() - t0


async def _run_round_trip(tree: Tree, rate_hz: float) -> float:
    """One goal through the RosAction at ``tree``'s root, the tree run at ``rate_hz``."""
    tree.reset()
    t0 = time.perf_counter()
    state = await tree.run(rate_hz)
    if state is not State.SUCCEEDED:
        raise RuntimeError(f"bench: the goal ended {state.value}: {tree.root.error}")
    return time.perf_counter() - t0


async def _jitter(root: Node, seconds: float, rate_hz: float = 200.0) -> dict[str, Any]:
    """How late each tick of ``root`` at ``rate_hz`` is (µs), ticked for ``seconds``."""
    tree = Tree(root)
    tree.setup()
    period = 1.0 / rate_hz
    late: list[float] = []
    loop = asyncio.get_running_loop()
    start = deadline = loop.time()
    while deadline - start < seconds:
        late.append((loop.time() - deadline) * 1e6)
        tree.tick()
        deadline += period
        await asyncio.sleep(max(0.0, deadline - loop.time()))
    tree.untick()
    return {"late_us": percentiles(late), "ticks": len(late)}


async def _measure(domain: int, rounds: int, seconds: float) -> dict[str, Any]:
    peer = _RclpyClient(domain)
    try:
        async with RosBridge(RosSettings(domain_id=domain, node_name="bench"), robot="bench") as b:
            node = RosAction(
                "rt", action_type=FIB, action_name="instant", bridge=b, inputs={"order": 1}
            )
            tree = Tree(node)
            tree.setup()
            for _ in range(1000):  # discovery: the node's client sees the server
                if b.server_ready("action", FIB, "instant"):
                    break
                await asyncio.sleep(0.01)
            woken = asyncio.Event()
            b.wake_on(woken.set)
            for _ in range(20):  # warm-up: discovery, first allocations
                peer.round_trip()
                await _node_round_trip(tree, woken)
            rclpy_s, woken_s, polled_s = [], [], []
            for _ in range(rounds):
                rclpy_s.append(peer.round_trip())
                woken_s.append(await _node_round_trip(tree, woken))
                polled_s.append(await _node_round_trip(tree, None))
            b.wake_on(None)
            await tree.shutdown()
            run_s: dict[str, list[float]] = {"rclpy": [], "nudged": [], "periodic": []}
            for i in range(min(rounds, 100)):  # periodic: ~1 period (100 ms) a round
                for nudges in (True, False):
                    b.nudges = nudges
                    ran = Tree(
                        RosAction("rt", action_type=FIB, action_name="instant", inputs={"order": 1})
                    )
                    give(b, ran)
                    if nudges or i < 30:
                        run_s["nudged" if nudges else "periodic"].append(
                            await _run_round_trip(ran, AGENT_HZ)
                        )
                    await ran.shutdown()
                run_s["rclpy"].append(peer.round_trip())
            b.nudges = True
            idle = await _jitter(AlwaysRunning("idle"), seconds)
            stream = RosAction(
                "stream",
                action_type=FIB,
                action_name="stream",
                bridge=b,
                inputs={"order": int(seconds * 1000) + 2000},
            )
            fed = await _jitter(stream, seconds)
            feedback = stream.outputs["feedback_sequence"]
    finally:
        peer.close()
    rt = {
        k: percentiles([s * 1e6 for s in v])
        for k, v in (
            ("rclpy_us", rclpy_s),
            ("btcap_woken_us", woken_s),
            ("btcap_polled_1khz_us", polled_s),
        )
    }
    runs = {f"{k}_us": percentiles([s * 1e6 for s in v]) for k, v in run_s.items()}
    return {
        "round_trip": rt,
        "round_trip_tree_run_10hz": runs,
        "ratio_nudged_to_rclpy_p50": runs["nudged_us"]["p50"] / runs["rclpy_us"]["p50"],
        "ratio_periodic_to_rclpy_p50": runs["periodic_us"]["p50"] / runs["rclpy_us"]["p50"],
        "ratio_woken_to_rclpy_p50": rt["btcap_woken_us"]["p50"] / rt["rclpy_us"]["p50"],
        "ratio_polled_to_rclpy_p50": rt["btcap_polled_1khz_us"]["p50"] / rt["rclpy_us"]["p50"],
        "jitter_200hz": {"idle": idle, "with_1khz_feedback": fed},
        "jitter_ratio_p99": fed["late_us"]["p99"] / max(idle["late_us"]["p99"], 1.0),
        "feedback_seen_last": feedback,
        "rounds": rounds,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Measure, print and write ``bench/results/ros.json``."""
    domain = int(os.environ.get("ROS_DOMAIN_ID") or random.randint(1, 101))
    server = _server(domain)
    try:
        load_before = os.getloadavg()[0]
        data = asyncio.run(_measure(domain, 50 if quick else 300, 1.0 if quick else 3.0))
    finally:
        if server.stdin is not None:
            server.stdin.close()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        if server.stdout is not None:
            server.stdout.close()
    data["loadavg"] = {"before": load_before, "after": os.getloadavg()[0]}
    data["quick"] = quick
    rt = data["round_trip"]
    print("goal -> result round trip (µs, p50 / p99):")
    for name, p in rt.items():
        print(f"  {name:24s} {p['p50']:8.0f} / {p['p99']:8.0f}")
    print(f"  ratio btcap (woken) / rclpy, p50: {data['ratio_woken_to_rclpy_p50']:.2f}")
    print(f"  ratio btcap (polled 1 kHz) / rclpy, p50: {data['ratio_polled_to_rclpy_p50']:.2f}")
    print(f"goal -> result round trip, tree run at {AGENT_HZ:g} Hz (µs, p50 / p99):")
    for name, p in data["round_trip_tree_run_10hz"].items():
        print(f"  {name:24s} {p['p50']:8.0f} / {p['p99']:8.0f}")
    print(f"  ratio nudged / rclpy, p50: {data['ratio_nudged_to_rclpy_p50']:.2f}")
    print(f"  ratio periodic / rclpy, p50: {data['ratio_periodic_to_rclpy_p50']:.2f}")
    j = data["jitter_200hz"]
    for name, v in j.items():
        p = v["late_us"]
        print(
            f"tick lateness at 200 Hz, {name:20s}: p50 {p['p50']:6.0f} µs, p99 {p['p99']:6.0f} µs"
        )
    load = data["loadavg"]
    print(f"load average before/after: {load['before']:.2f} / {load['after']:.2f}")
    path = write_result("ros", data)
    print(f"wrote {path}")
    return data
