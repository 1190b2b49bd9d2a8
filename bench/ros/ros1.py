"""ROS 1 bridge benchmark: a goal's round trip through btcap's RosAction (its rospy node
in a process of its own, :mod:`btcap.ros.client1`) against actionlib's own
``SimpleActionClient`` on the same server in the same run.

Needs Debian's rospy (`make ros1`): ``make bench-ros1`` (python -m btcap.bench ros1 with
.venv-ros1). It starts a ``rosmaster`` of its own on a free loopback port and an actionlib
server (``actionlib/Test`` ``instant``: SUCCEEDED at once) in a process of its own
(``python -m btcap.bench.ros.ros1 serve``). The peer is a SimpleActionClient in this process
(its ``send_goal`` then ``wait_for_result``, the usual shape); btcap's node is ticked by
the event loop when the bridge says a goal answered (``wake_on``). They take turns round by
round, who goes first alternating (the server has just served either one alike), so load
elsewhere on the machine lands on both alike.
"""

from __future__ import annotations

import asyncio
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from btcap.bench.common import percentiles, write_result
from btcap.bt.state import State
from btcap.bt.tree import Tree
from btcap.ros import rpc1
from btcap.ros.client1 import Ros1Bridge
from btcap.ros.nodes1 import RosAction
from btcap.team.rossettings import RosSettings

__all__ = ["run"]

TEST = "actionlib/Test"
NAMESPACE = "/bench"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _start_master(home: Path) -> tuple[subprocess.Popen[bytes], str]:
    """``rosmaster --core`` on a free loopback port; this process's environment points
    ROS 1 at it (loopback only, logs under ``home``)."""
    exe = shutil.which("rosmaster", path=f"{os.environ.get('PATH', '')}:/usr/bin")
    if exe is None:
        raise RuntimeError("bench ros1: rosmaster is not installed (`make ros1`)")
    port = _free_port()
    uri = f"http://127.0.0.1:{port}/"
    for key in [k for k in os.environ if k.startswith("ROS_")]:
        del os.environ[key]
    os.environ.update(
        ROS_MASTER_URI=uri, ROS_IP="127.0.0.1", ROS_HOME=str(home), ROS_LOG_DIR=str(home / "log")
    )
    master = subprocess.Popen([exe, "--core", "-p", str(port)], stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 30.0
    while True:
        try:
            rpc1.call(uri, "getPid", "/bench", timeout_s=2.0)
            return master, uri
        except rpc1.RosCallError:  # not up yet
            pass
        if time.monotonic() > deadline or master.poll() is not None:
            master.kill()
            raise RuntimeError("bench ros1: rosmaster did not start")
        time.sleep(0.05)


def _start_server() -> subprocess.Popen[str]:
    env = {**os.environ, "ROS_NAMESPACE": NAMESPACE}
    cmd = [sys.executable, "-m", "btcap.bench.ros.ros1", "serve"]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    if proc.stdout.readline().strip() != "ready":
        proc.kill()
        raise RuntimeError("bench ros1: the actionlib server did not start")
    return proc


def serve() -> None:
    """The server process: ``instant`` succeeds every goal at once; until stdin closes."""
    import actionlib
    import rospy
    from actionlib.msg import TestAction, TestResult

    rospy.init_node("server", disable_signals=True)
    server: Any = None

    def execute(goal: Any) -> None:
        server.set_succeeded(TestResult(result=goal.goal))

    server = actionlib.SimpleActionServer("instant", TestAction, execute, auto_start=False)
    server.start()
    print("ready", flush=True)
    sys.stdin.read()
    rospy.signal_shutdown("bench over")


class _Peer:
    """actionlib's SimpleActionClient on this process's rospy node."""

    def __init__(self) -> None:
        import actionlib
        import rospy
        from actionlib.msg import TestAction, TestGoal

        self.rospy = rospy
        rospy.init_node("peer", disable_signals=True)
        self.client = actionlib.SimpleActionClient(f"{NAMESPACE}/instant", TestAction)
        if not self.client.wait_for_server(rospy.Duration(30.0)):
            raise RuntimeError("bench ros1: SimpleActionClient found no server")
        self.goal = TestGoal(goal=1)

    def round_trip(self) -> float:
        t0 = time.perf_counter()
        self.client.send_goal(self.goal)
        if not self.client.wait_for_result(self.rospy.Duration(10.0)):
            raise RuntimeError("bench ros1: actionlib's goal did not finish")
        return time.perf_counter() - t0

    def close(self) -> None:
        self.client.action_client.stop()
        self.rospy.signal_shutdown("bench over")


async def _node_round_trip(tree: Tree, woken: asyncio.Event) -> float:
    t0 = time.perf_counter()
    state = tree.tick()
    while state is State.RUNNING:
        await woken.wait()
        woken.clear()
        state = tree.tick()
    if state is not State.SUCCEEDED:
        raise RuntimeError(f"bench ros1: the goal ended {state.value}: {tree.root.error}")
    return time.perf_counter() - t0


async def _measure(uri: str, rounds: int) -> dict[str, Any]:
    peer = await asyncio.to_thread(_Peer)
    try:
        settings = RosSettings(backend="ros1", master_uri=uri, node_name="btcap")
        async with Ros1Bridge(settings, robot="bench") as bridge:
            node = RosAction(
                "rt", action_type=TEST, action_name="instant", bridge=bridge, inputs={"goal": 1}
            )
            tree = Tree(node)
            tree.setup()
            for _ in range(3000):  # the node's client connects to the server
                if bridge.server_ready("action", TEST, "instant"):
                    break
                await asyncio.sleep(0.01)
            woken = asyncio.Event()
            bridge.wake_on(woken.set)
            for _ in range(20):  # warm-up: connections, first allocations
                peer.round_trip()
                await _node_round_trip(tree, woken)
            actionlib_s, btcap_s = [], []
            for i in range(rounds):  # who goes first alternates: neither follows the other
                if i % 2:
                    actionlib_s.append(peer.round_trip())
                btcap_s.append(await _node_round_trip(tree, woken))
                if not i % 2:
                    actionlib_s.append(peer.round_trip())
            bridge.wake_on(None)
    finally:
        peer.close()
    rt = {
        "actionlib_simple_client_us": percentiles([s * 1e6 for s in actionlib_s]),
        "btcap_woken_us": percentiles([s * 1e6 for s in btcap_s]),
    }
    return {
        "round_trip": rt,
        "ratio_btcap_to_actionlib_p50": rt["btcap_woken_us"]["p50"]
        / rt["actionlib_simple_client_us"]["p50"],
        "rounds": rounds,
    }


def _reap(proc: subprocess.Popen[Any]) -> None:
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def run(quick: bool = False) -> dict[str, Any]:
    """Measure, print and write ``bench/results/ros1.json``."""
    with tempfile.TemporaryDirectory(prefix="btcap-bench-ros1-") as home:
        master, uri = _start_master(Path(home))
        server: subprocess.Popen[str] | None = None
        try:
            server = _start_server()
            load_before = os.getloadavg()[0]
            data = asyncio.run(_measure(uri, 50 if quick else 300))
        finally:
            if server is not None:
                if server.stdin is not None:
                    server.stdin.close()
                _reap(server)
                if server.stdout is not None:
                    server.stdout.close()
            master.terminate()
            _reap(master)
    data["loadavg"] = {"before": load_before, "after": os.getloadavg()[0]}
    data["quick"] = quick
    print("goal -> result round trip (µs, p50 / p99):")
    for name, p in data["round_trip"].items():
        print(f"  {name:28s} {p['p50']:8.0f} / {p['p99']:8.0f}")
    print(f"  ratio btcap / actionlib, p50: {data['ratio_btcap_to_actionlib_p50']:.2f}")
    load = data["loadavg"]
    print(f"load average before/after: {load['before']:.2f} / {load['after']:.2f}")
    print(f"wrote {write_result('ros1', data)}")
    return data


if __name__ == "__main__":
    if sys.argv[1:] == ["serve"]:
        serve()
    else:
        run(quick="--quick" in sys.argv)
