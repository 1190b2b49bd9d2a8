"""The simulation manager behind ROS 1: :mod:`btcap.sim.ros1.child` serves every robot's
``move_base``, operation services and topics from a rospy process of its own; this is the
mission's side of it.

A reader thread takes the child's ``ask`` frames and asks the
:class:`~btcap.sim.world.manager.SimulationManager` through the actor system on the mission's
event loop (nothing here touches its state), writing each answer back when it comes; a
``cancel`` (the goal was preempted) stops the robot, as the ROS 2 servers do. :meth:`publish`
is the manager's ``on_position`` hook: one short write on the event loop. Starting and
closing block (a thread).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import os
import socket
import subprocess
import sys
import threading
from collections import Counter
from collections.abc import Collection
from multiprocessing.connection import Connection
from typing import Any

import msgspec

from btcap.actors import ActorError, ActorRef, TimeSource
from btcap.errors import BtcapError
from btcap.sim.ros2.names import OPERATIONS
from btcap.sim.world.distance import Cell
from btcap.sim.world.messages import MoveTo, Operate, PositionUpdate, SimResult, StopRobot
from btcap.sim.world.model import RobotModel
from btcap.transports.log import get_logger

__all__ = ["Ros1SimError", "SimServers1"]

log = get_logger(__name__)

#: Bounds, not measures: the rospy process imports and registers in about a second.
START_S = 60.0
STOP_S = 10.0


class Ros1SimError(BtcapError, RuntimeError):
    """The simulation's ROS 1 process did not come up or went away."""


class SimServers1:
    """Every simulated robot's ROS 1 servers, in one rospy process on ``master_uri``
    (namespaces from ``namespaces``), until :meth:`close`; those of ``absent`` robots (they
    join later) from when :meth:`serve` puts them in the graph."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        manager: ActorRef[Any],
        robots: dict[str, RobotModel],
        *,
        namespaces: dict[str, str],
        cell_size_m: float,
        start: Cell,
        clock: TimeSource,
        master_uri: str,
        env: dict[str, str] | None = None,
        absent: Collection[str] = (),
    ) -> None:
        self.loop, self.ref, self.clock = loop, manager, clock
        # As the in-process leaves ask: an hour of the clock, in wall seconds, with margin.
        self.timeout = max(2.0, clock.to_wall(3600.0) * 3 + 2.0)
        #: Goals and calls taken per robot and per server (move_base, explore, ...).
        self.counts: dict[str, Counter[str]] = {name: Counter() for name in robots}
        self._asks: dict[int, concurrent.futures.Future[SimResult]] = {}
        self._robot_of: dict[int, str] = {}
        self._lock = threading.Lock()
        self._send = threading.Lock()
        self._closed = False
        config = {
            "cell_size_m": cell_size_m,
            "start": list(start),
            "robots": [
                {
                    "name": name,
                    "namespace": namespaces[name],
                    "operations": [op for op in OPERATIONS if model.can(op)],
                }
                for name, model in robots.items()
            ],
            "absent": sorted(absent),
        }
        ours, theirs = socket.socketpair()
        for end in (ours, theirs):
            end.setblocking(True)
        base = env if env is not None else dict(os.environ)
        with theirs:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "btcap.sim.ros1.child", str(theirs.fileno())],
                pass_fds=(theirs.fileno(),),
                env=dict(base, ROS_MASTER_URI=master_uri),
                stdin=subprocess.DEVNULL,
            )
        self.conn = Connection(ours.detach())
        try:
            self._post(["config", config])
            if not self.conn.poll(START_S):
                raise Ros1SimError(f"the simulation's ROS 1 node: not up within {START_S} s")
            up = msgspec.json.decode(self.conn.recv_bytes())
            if up[0] != "up" or up[1]:
                raise Ros1SimError(f"the simulation's ROS 1 node on {master_uri}: {up[1]}")
        except BaseException as exc:
            self.close()
            if isinstance(exc, EOFError | OSError):
                raise Ros1SimError("the simulation's ROS 1 process ended at start") from None
            raise
        self._reader = threading.Thread(target=self._read, name="btcap sim ros1", daemon=True)
        self._reader.start()

    def _post(self, frame: list[Any]) -> None:
        data = msgspec.json.encode(frame)
        with self._send:
            self.conn.send_bytes(data)

    # -- the child's asks, on the reader thread ------------------------------------------
    def _read(self) -> None:
        while True:
            try:
                frame = msgspec.json.decode(self.conn.recv_bytes())
            except (EOFError, OSError):
                break
            if frame[0] == "ask":
                self._ask(*frame[1:])
            elif frame[0] == "cancel":
                with self._lock:
                    answer = self._asks.pop(frame[1], None)
                    robot = self._robot_of.pop(frame[1], None)
                if answer is not None:
                    answer.cancel()
                if robot is not None:
                    self.loop.call_soon_threadsafe(self.ref.tell, StopRobot(robot))
        if not self._closed:
            log.error("sim.ros1_gone", why="the simulation's ROS 1 process ended")

    def _ask(self, qid: int, robot: str, what: str, row: int, col: int, target: int) -> None:
        move = what == "move_base"
        msg: MoveTo | Operate = MoveTo(robot, (row, col)) if move else Operate(robot, what, target)
        with self._lock:
            self.counts.setdefault(robot, Counter())[what] += 1

        async def ask() -> SimResult:
            try:
                got: SimResult = await self.ref.ask(msg, expect=SimResult, timeout=self.timeout)
            except ActorError as exc:
                self.ref.tell(StopRobot(robot))
                return SimResult(False, (0, 0), str(exc))
            return got

        answer = asyncio.run_coroutine_threadsafe(ask(), self.loop)
        with self._lock:
            self._asks[qid] = answer
            self._robot_of[qid] = robot
        answer.add_done_callback(lambda f: self._answer(qid, f))

    def _answer(self, qid: int, answer: concurrent.futures.Future[SimResult]) -> None:
        with self._lock:
            self._asks.pop(qid, None)
            self._robot_of.pop(qid, None)
        if answer.cancelled() or self._closed:
            return
        exc = answer.exception()
        got = SimResult(False, (0, 0), str(exc)) if exc is not None else answer.result()
        found, contaminated = int(got.found), bool(got.contaminated)
        with contextlib.suppress(OSError):
            self._post(["answer", qid, bool(got.ok), got.detail, found, contaminated])

    # -- the manager's word, on the event loop -------------------------------------------
    def publish(self, msg: PositionUpdate) -> None:
        """Publish where ``msg``'s robot is (its pose and state topics): one short write."""
        if self._closed:
            return
        row, col = int(msg.position[0]), int(msg.position[1])
        frame = ["state", msg.robot, row, col, msg.op, int(msg.target), msg.phase]
        with contextlib.suppress(OSError):
            self._post([*frame, self.clock.now()])

    def withdraw(self, robot: str) -> None:
        """Take ``robot``'s servers and topics out of the ROS graph (the robot's body is
        gone; its agent may live on): its clients see them go, its bids stop."""
        if not self._closed:
            with contextlib.suppress(OSError):  # the process is gone: so are the servers
                self._post(["withdraw", robot])

    def serve(self, robot: str) -> None:
        """Put ``robot``'s withdrawn (or not yet served) servers and topics in the ROS graph."""
        if not self._closed:
            with contextlib.suppress(OSError):  # the process is gone: so are the servers
                self._post(["serve", robot])

    def served(self) -> dict[str, dict[str, int]]:
        """Goals and calls each robot's servers took, per server."""
        with self._lock:
            return {name: dict(c) for name, c in self.counts.items()}

    def close(self) -> None:
        """Have the rospy process unregister and exit; reap it (blocks: a thread)."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(OSError):
            self._post(["stop"])
        try:
            self.process.wait(timeout=STOP_S)
        except subprocess.TimeoutExpired:
            log.warning("sim.ros1_kill", why=f"no exit in {STOP_S} s")
            self.process.kill()
            self.process.wait()
        self.conn.close()
        reader = getattr(self, "_reader", None)
        if reader is not None:
            reader.join(timeout=STOP_S)
        with self._lock:
            asks, self._asks = list(self._asks.values()), {}
        for answer in asks:
            answer.cancel()
