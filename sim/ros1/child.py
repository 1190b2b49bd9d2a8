"""The simulation's rospy process: every simulated robot's ROS 1 servers, as the paper set
them up, driven by :class:`~btcap.sim.ros1.server.SimServers1` over a socket pair.

Per robot, in its namespace: ``move_base`` (an actionlib ``SimpleActionServer`` of
``move_base_msgs/MoveBaseAction``, feedback a pose per cell driven into, preempt stopping
the robot), a ``btcap_sim1_msgs/Operate`` service per operation the robot can do, and the
latched ``pose`` (``geometry_msgs/PoseStamped``) and ``state`` (``btcap_sim1_msgs/RobotState``)
topics. rospy allows one ``init_node`` per process and runs each goal and call on threads of
its own: those threads ask the simulation through the parent (an ``ask`` frame, answered by
an ``answer`` frame) and wait; nothing of rospy is in the mission's process.

Frames are msgspec JSON lists: down ``["config", {...}]`` (its ``absent`` robots are not
served until a ``serve``: they join later), ``["answer", qid, ok, detail,
found, contaminated]``, ``["state", robot, row, col, op, target, phase, t]``,
``["withdraw", robot]`` (its executions give up, the robot stopping, and its servers
leave the graph), ``["serve", robot]`` (they come
back, where the robot was last told to be), ``["stop"]``;
up ``["up", error]``, ``["ask", qid, robot, what, row, col, target]`` (``what``:
``move_base`` or an operation), ``["cancel", qid]``. Run as ``python -m
btcap.sim.ros1.child FD`` with ``ROS_MASTER_URI`` set.
"""

from __future__ import annotations

import itertools
import socket
import sys
import threading
import time
from multiprocessing.connection import Connection
from typing import Any

import msgspec

from btcap.sim.ros2.names import FRAME, cell_of, xy_of

__all__ = ["main"]

#: Seconds a goal's thread waits between two looks at its goal (preempted? moved on?).
POLL_S = 0.01
#: Seconds a withdraw waits for the robot's executions to end (a bound).
STOP_S = 5.0


class Sim:
    """The servers of every robot, on one rospy node."""

    def __init__(self, conn: Connection, config: dict[str, Any]) -> None:
        import rospy

        self.rospy = rospy
        self.conn = conn
        self.size = float(config["cell_size_m"])
        self.closing = threading.Event()
        self._send = threading.Lock()
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._pending: dict[int, tuple[threading.Event, list[Any]]] = {}
        start = self.start = (int(config["start"][0]), int(config["start"][1]))
        #: Each robot's namespace and operations, to serve it again after a withdraw.
        self.config = {r["name"]: (r["namespace"], r["operations"]) for r in config["robots"]}
        #: Robots out of the graph: withdrawn, or not joined yet (served from their join).
        self.withdrawn: set[str] = set(config.get("absent", ()))
        self.robots = {
            name: _Robot(self, name, *c, start)
            for name, c in self.config.items()
            if name not in self.withdrawn
        }
        #: Each robot's last ``state`` frame's fields, published again when it is served again.
        self.last: dict[str, list[Any]] = {}

    # -- frames -------------------------------------------------------------------
    def post(self, frame: list[Any]) -> None:
        data = msgspec.json.encode(frame)
        with self._send:
            self.conn.send_bytes(data)

    def ask(self, robot: str, what: str, cell: tuple[int, int], target: int) -> int:
        qid = next(self._ids)
        with self._lock:
            self._pending[qid] = (threading.Event(), [])
        self.post(["ask", qid, robot, what, cell[0], cell[1], target])
        return qid

    def wait(self, qid: int, preempted: Any = None, feedback: Any = None) -> list[Any] | None:
        """The answer to ``qid``; None (the parent told to cancel it) once ``preempted()``
        or the process is closing."""
        with self._lock:
            done, box = self._pending[qid]
        try:
            while not done.wait(POLL_S):
                if self.closing.is_set() or (preempted is not None and preempted()):
                    self.post(["cancel", qid])
                    return None
                if feedback is not None:
                    feedback()
            return box
        finally:
            with self._lock:
                self._pending.pop(qid, None)

    def serve_again(self, name: str) -> None:
        """A withdrawn (or joining) robot's servers and topics back, its last state
        published."""
        self.withdrawn.discard(name)
        robot = self.robots[name] = _Robot(self, name, *self.config[name], self.start)
        last = self.last.get(name)
        if last is not None:
            robot.publish(*last)

    def run(self) -> None:
        """Act on the parent's frames until ``stop`` or the pipe closing."""
        while True:
            try:
                frame = msgspec.json.decode(self.conn.recv_bytes())
            except (EOFError, OSError):
                break
            kind = frame[0]
            if kind == "answer":
                with self._lock:
                    got = self._pending.get(frame[1])
                if got is not None:
                    got[1].extend(frame[2:])
                    got[0].set()
            elif kind == "state":
                self.last[frame[1]] = frame[2:]
                robot = self.robots.get(frame[1])
                if robot is not None:
                    robot.publish(*frame[2:])
            elif kind == "withdraw":
                gone = self.robots.pop(frame[1], None)
                if gone is not None:
                    self.withdrawn.add(frame[1])
                    gone.close()
            elif kind == "serve" and frame[1] in self.withdrawn:
                self.serve_again(frame[1])
            elif kind == "stop":
                break
        self.closing.set()
        for robot in self.robots.values():
            robot.close()


class _Robot:
    """One robot's move_base action server, operation services and topics."""

    def __init__(
        self, sim: Sim, name: str, namespace: str, operations: list[str], start: tuple[int, int]
    ) -> None:
        import actionlib
        from btcap_sim1_msgs.msg import RobotState
        from btcap_sim1_msgs.srv import Operate
        from geometry_msgs.msg import PoseStamped
        from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseResult

        rospy = sim.rospy
        self.sim, self.name = sim, name
        self.cell = start
        self.phase = ""
        #: Set when the robot's servers leave the graph: executions give up (the robot
        #: stops, its goals end ABORTED), as behind ROS 2.
        self.withdrawn = threading.Event()
        self.running = 0
        self._lock = threading.Lock()
        self._types = (PoseStamped, RobotState, MoveBaseFeedback, MoveBaseResult)
        ns = namespace.rstrip("/")
        self.server = actionlib.SimpleActionServer(
            f"{ns}/move_base", MoveBaseAction, execute_cb=self._navigate, auto_start=False
        )
        self.services = [
            rospy.Service(f"{ns}/{op}", Operate, self._operation(op)) for op in operations
        ]
        self.pose_pub = rospy.Publisher(f"{ns}/pose", PoseStamped, queue_size=10, latch=True)
        self.state_pub = rospy.Publisher(f"{ns}/state", RobotState, queue_size=100, latch=True)
        self.server.start()

    def pose(self, cell: tuple[int, int], t: float) -> Any:
        pose = self._types[0]()
        pose.header.frame_id = FRAME
        pose.header.stamp = self.sim.rospy.Time.from_sec(max(0.0, t))
        pose.pose.position.x, pose.pose.position.y = xy_of(cell, self.sim.size)
        pose.pose.orientation.w = 1.0
        return pose

    def publish(self, row: int, col: int, op: str, target: int, phase: str, t: float) -> None:
        self.cell, self.phase = (row, col), phase
        self.pose_pub.publish(self.pose(self.cell, t))
        state = self._types[1](row=row, col=col, operation=op, target=target, phase=phase)
        self.state_pub.publish(state)

    def _gone(self) -> bool:
        return self.withdrawn.is_set()

    def _count(self, n: int) -> None:
        with self._lock:
            self.running += n

    def _navigate(self, goal: Any) -> None:  # the server's execute thread
        self._count(1)
        try:
            if self._gone():  # accepted as the robot was withdrawn: never drive it
                self.server.set_aborted(self._types[3](), "the robot's servers were withdrawn")
                return
            self._navigate_to(goal)
        finally:
            self._count(-1)

    def _navigate_to(self, goal: Any) -> None:
        p = goal.target_pose.pose.position
        target = cell_of(p.x, p.y, self.sim.size)
        qid = self.sim.ask(self.name, "move_base", target, -1)
        told: list[tuple[int, int]] = []

        def feedback() -> None:
            cell = self.cell
            if told[-1:] != [cell]:
                told.append(cell)
                self.server.publish_feedback(self._types[2](base_position=self.pose(cell, 0.0)))

        preempted = lambda: self.server.is_preempt_requested() or self._gone()  # noqa: E731
        got = self.sim.wait(qid, preempted, feedback)
        if got is None and self._gone():
            self.server.set_aborted(self._types[3](), "the robot's servers were withdrawn")
        elif got is None:
            self.server.set_preempted(self._types[3](), "preempted: the robot stopped")
        elif got[0]:
            self.server.set_succeeded(self._types[3](), f"at {list(target)}")
        else:
            self.server.set_aborted(self._types[3](), str(got[1]))

    def _operation(self, op: str) -> Any:
        def call(request: Any) -> Any:  # a thread of rospy's per connection
            self._count(1)
            try:
                return operate(request)
            finally:
                self._count(-1)

        def operate(request: Any) -> Any:
            if self._gone():  # came as the robot was withdrawn: never ask the simulation
                return (False, "withdrawn", 0, False)
            qid = self.sim.ask(self.name, op, self.cell, int(request.target))
            got = self.sim.wait(qid, self._gone)
            if got is None:
                why = "withdrawn" if self._gone() else "the simulation is closing"
                return (False, why, 0, False)
            ok, detail, found, contaminated = got
            return (bool(ok), str(detail), int(found), bool(contaminated))

        return call

    def _busy(self) -> bool:
        """Whether an execution runs or a goal is on its way to one: accepted by actionlib
        (ACTIVE) but its execute callback not counted yet, or waiting (PENDING) for the
        server's loop, which takes it up to 0.1 s after the goal it preempted ended. Under
        the server's locks (in the order actionlib takes them), so a goal's acceptance is
        seen whole."""
        server = self.server
        with server.action_server.lock, server.lock:
            return bool(self.running) or server.is_active() or server.is_new_goal_available()

    def close(self) -> None:
        """Leave the ROS graph: executions give up (waited for, a bound), goals accepted
        or waiting meanwhile too (they end ABORTED without driving), then the action
        server, services and topics unregistered."""
        self.withdrawn.set()
        deadline = time.monotonic() + STOP_S
        actions = self.server.action_server
        while True:
            with actions.lock:  # no goal comes between the last look and the stop
                if not self._busy() or time.monotonic() >= deadline:
                    actions.stop()
                    break
            time.sleep(POLL_S)
        for service in self.services:
            service.shutdown("the simulation stopped")
        self.pose_pub.unregister()
        self.state_pub.unregister()


def main(argv: list[str]) -> int:
    conn = Connection(socket.socket(fileno=int(argv[0])).detach())
    config = msgspec.json.decode(conn.recv_bytes())[1]
    try:
        import rospy

        rospy.init_node("btcap_sim", disable_signals=True)
        sim = Sim(conn, config)
    except Exception as exc:
        text = str(exc).strip().splitlines()
        conn.send_bytes(msgspec.json.encode(["up", text[0] if text else type(exc).__name__]))
        return 1
    sim.post(["up", ""])
    try:
        sim.run()
    finally:
        rospy.signal_shutdown("the simulation stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
