"""The simulation manager behind ROS 2: per simulated robot, in its namespace, a navigation
action with feedback, an action per operation it can do, a pose and a state topic and a stop
service, each backed by the same :class:`~btcap.sim.world.manager.SimulationManager`.

Imports rclpy: loaded in a thread by :mod:`btcap.sim.ros2.host`, never at start-up. The
servers run on an rclpy executor thread of their own; each goal's execution blocks one of
its threads while it waits for the manager's answer, which it asks for through the actor
system on the mission's event loop (nothing here touches the manager's state directly).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import math
import threading
import time
from collections import Counter
from collections.abc import Callable, Collection
from typing import Any

import rclpy
from btcap_sim_msgs.action import NavigateToPose
from btcap_sim_msgs.action import Operate as OperateAction
from btcap_sim_msgs.msg import RobotState
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from btcap.actors import ActorError, ActorRef, TimeSource
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros2.names import FRAME, OPERATIONS, RobotNames, cell_of, xy_of
from btcap.sim.world.distance import Cell
from btcap.sim.world.messages import MoveTo, Operate, PositionUpdate, SimResult, StopRobot
from btcap.sim.world.model import RobotModel

__all__ = ["SimServers", "pose_at"]

#: Wall seconds an execution waits between two looks at its goal (cancel requested? the
#: robot moved on?) while the manager works on it.
_POLL_S = 0.01
#: Wall seconds a withdraw waits for the robot's executions to end (a bound).
STOP_S = 5.0


def pose_at(cell: Cell, cell_size_m: float, t: float) -> PoseStamped:
    """A cell as a pose in :data:`~btcap.sim.ros2.names.FRAME`, stamped ``t`` clock seconds."""
    pose = PoseStamped()
    pose.header.frame_id = FRAME
    sec = math.floor(t)
    pose.header.stamp = Time(sec=sec, nanosec=min(999_999_999, int((t - sec) * 1e9)))
    pose.pose.position.x, pose.pose.position.y = xy_of(cell, cell_size_m)
    pose.pose.orientation.w = 1.0
    return pose


class _Manager:
    """The simulation manager as the executor's threads reach it: asks and tells run on the
    mission's event loop."""

    def __init__(
        self, loop: asyncio.AbstractEventLoop, ref: ActorRef[Any], clock: TimeSource
    ) -> None:
        self.loop = loop
        self.ref = ref
        # As the in-process leaves ask: an hour of the clock, in wall seconds, with margin.
        self.timeout = max(2.0, clock.to_wall(3600.0) * 3 + 2.0)
        #: Set as the servers close: executions still waiting give up (the robot stops).
        self.closing = threading.Event()

    def ask(self, msg: MoveTo | Operate) -> concurrent.futures.Future[SimResult]:
        async def ask() -> SimResult:
            try:
                result: SimResult = await self.ref.ask(msg, expect=SimResult, timeout=self.timeout)
            except ActorError as exc:
                self.ref.tell(StopRobot(msg.robot))
                return SimResult(False, (0, 0), str(exc))
            return result

        return asyncio.run_coroutine_threadsafe(ask(), self.loop)

    def stop(self, robot: str) -> None:
        self.loop.call_soon_threadsafe(self.ref.tell, StopRobot(robot))


class _RobotServer:
    """One robot's servers and publishers, on a node in its namespace."""

    def __init__(
        self,
        node: Node,
        robot: str,
        model: RobotModel,
        manager: _Manager,
        cell_size_m: float,
        start: Cell,
        clock: TimeSource,
        ros: ScenarioRos,
    ) -> None:
        from btcap.ros.client import RosBridge

        self.node = node
        self.robot = robot
        self.manager = manager
        self.cell_size_m = cell_size_m
        self.clock = clock
        names = RobotNames(robot, ros.namespace_of(robot))
        # As the manager last said (the event loop writes, executions read: plain values).
        self.cell: Cell = start
        self.phase = ""
        #: Goals taken per action (navigate_to_pose, explore, ...), for a run's record.
        self.served: Counter[str] = Counter()
        self._lock = threading.Lock()
        #: Set when the robot's servers leave the graph: executions give up, nothing is
        #: published any more (under ``_lock``, so no publish runs on a destroyed publisher).
        self.withdrawn = threading.Event()
        #: Executions running (a withdraw waits for them to end before destroying).
        self.running = 0
        group = ReentrantCallbackGroup()
        accept: Callable[[Any], CancelResponse] = lambda _: CancelResponse.ACCEPT  # noqa: E731
        self.servers = [
            ActionServer(
                node,
                NavigateToPose,
                names.navigate,
                self._navigate,
                cancel_callback=accept,
                callback_group=group,
            )
        ]
        for op in OPERATIONS:
            if model.can(op):
                self.servers.append(
                    ActionServer(
                        node,
                        OperateAction,
                        names.operate(op),
                        self._operation(op),
                        cancel_callback=accept,
                        callback_group=group,
                    )
                )
        self.pose_pub = node.create_publisher(PoseStamped, names.pose, RosBridge().qos(ros.qos))
        self.state_pub = node.create_publisher(RobotState, names.state, 100)
        node.create_service(Trigger, names.stop, self._stop, callback_group=group)

    # -- the manager's word, on the event loop ----------------------------------------
    def publish(self, msg: PositionUpdate) -> None:
        cell = (int(msg.position[0]), int(msg.position[1]))
        self.cell, self.phase = cell, msg.phase
        with self._lock:
            if not self.withdrawn.is_set():
                self._publish(cell, msg)

    def _publish(self, cell: Cell, msg: PositionUpdate) -> None:
        pose = pose_at(cell, self.cell_size_m, self.clock.now())
        self.pose_pub.publish(pose)
        self.state_pub.publish(
            RobotState(
                pose=pose,
                row=cell[0],
                col=cell[1],
                operation=msg.op,
                target=msg.target,
                phase=msg.phase,
            )
        )

    # -- executions, on the executor's threads ----------------------------------------
    def _count(self, action: str) -> None:
        with self._lock:
            self.served[action] += 1
            self.running += 1

    def _done(self) -> None:
        with self._lock:
            self.running -= 1

    def stop_executions(self, wait_s: float) -> None:
        """Publish nothing more; executions give up (their goals aborted), waited for
        ``wait_s`` at most (blocks: a thread)."""
        with self._lock:
            self.withdrawn.set()
        deadline = time.monotonic() + wait_s
        while self.running and time.monotonic() < deadline:
            time.sleep(_POLL_S)

    def destroy(self) -> None:
        """Out of the ROS graph: action servers are not destroyed with their node (left
        alone they stay in it, and clients would go on seeing a server that no longer
        answers)."""
        for action in self.servers:
            action.destroy()
        self.node.destroy_node()

    def _wait(
        self, goal: Any, answer: concurrent.futures.Future[SimResult], feedback: Callable[[], None]
    ) -> SimResult | None:
        """The manager's answer, or None if the goal was cancelled (the robot is stopped)
        or ROS is shutting down; ``feedback`` is called on every look meanwhile."""
        context = self.node.context
        while True:
            try:
                return answer.result(timeout=_POLL_S)
            except concurrent.futures.TimeoutError:
                pass
            gone = self.manager.closing.is_set() or self.withdrawn.is_set() or not context.ok()
            if goal.is_cancel_requested or gone:
                self.manager.stop(self.robot)
                answer.cancel()
                return None
            feedback()

    def _navigate(self, goal: Any) -> Any:
        self._count("navigate_to_pose")
        try:
            return self._navigate_to(goal)
        finally:
            self._done()

    def _navigate_to(self, goal: Any) -> Any:
        p = goal.request.pose.pose.position
        target = cell_of(p.x, p.y, self.cell_size_m)
        answer = self.manager.ask(MoveTo(self.robot, target))
        told: list[Cell] = []

        def feedback() -> None:
            cell = self.cell
            if told[-1:] != [cell]:
                told.append(cell)
                fb = NavigateToPose.Feedback()
                fb.current_pose = pose_at(cell, self.cell_size_m, self.clock.now())
                fb.distance_remaining = float(math.dist(cell, target) * self.cell_size_m)
                goal.publish_feedback(fb)

        got = self._wait(goal, answer, feedback)
        result = NavigateToPose.Result()
        if got is None:
            result.error_code, result.error_msg = NavigateToPose.Result.UNKNOWN, "cancelled"
            _end(goal, cancelled=True)
        elif got.ok:
            goal.succeed()
        else:
            result.error_code, result.error_msg = NavigateToPose.Result.UNKNOWN, got.detail
            goal.abort()
        return result

    def _operation(self, op: str) -> Callable[[Any], Any]:
        def execute(goal: Any) -> Any:
            self._count(op)
            try:
                return operate(goal)
            finally:
                self._done()

        def operate(goal: Any) -> Any:
            answer = self.manager.ask(Operate(self.robot, op, int(goal.request.target)))
            told: list[str] = []

            def feedback() -> None:
                phase = self.phase
                if phase in ("carry", "work") and told[-1:] != [phase]:
                    told.append(phase)
                    goal.publish_feedback(OperateAction.Feedback(phase=phase))

            got = self._wait(goal, answer, feedback)
            result = OperateAction.Result()
            if got is None:
                result.detail = "cancelled"
                _end(goal, cancelled=True)
                return result
            result.ok, result.detail, result.found = got.ok, got.detail, got.found
            result.contaminated = bool(got.contaminated)
            if got.ok:
                goal.succeed()
            else:
                goal.abort()
            return result

        return execute

    def _stop(self, _request: Any, response: Any) -> Any:
        self.manager.stop(self.robot)
        response.success, response.message = True, f"{self.robot} stopped"
        return response


def _end(goal: Any, *, cancelled: bool) -> None:
    """End a goal whose execution stopped early: cancelled if asked, else aborted."""
    if cancelled and goal.is_cancel_requested:
        goal.canceled()
    else:
        goal.abort()


class SimServers:
    """Every simulated robot's ROS 2 servers, in one rclpy context (one DDS participant) of
    their own, spun by an executor thread until :meth:`close`.

    Made in a thread (it imports and starts rclpy); :meth:`publish` is the manager's
    ``on_position`` hook and runs on the event loop. ``ros`` (a scenario's block; None:
    its defaults) names the domain (unless ``domain_id``), the namespaces and the QoS.
    ``absent`` robots (they join later) are served from when :meth:`serve` is called.
    """

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        manager: ActorRef[Any],
        robots: dict[str, RobotModel],
        *,
        cell_size_m: float,
        start: Cell,
        clock: TimeSource,
        domain_id: int | None = None,
        ros: ScenarioRos | None = None,
        absent: Collection[str] = (),
    ) -> None:
        ros = ros or ScenarioRos()
        self.context = Context()
        if domain_id is None:
            domain_id = ros.domain_id
        rclpy.init(context=self.context, domain_id=domain_id)
        self._manager = _Manager(loop, manager, clock)
        self._serve_args = (robots, cell_size_m, clock, ros)
        #: Withdraws and serves again, one at a time and in order, off the event loop.
        self._changes = concurrent.futures.ThreadPoolExecutor(1, "btcap sim ros2 graph")
        # Each robot runs at most a drive and an operation at once (plus one superseded,
        # ending): threads enough that no execution waits for a thread.
        threads = 3 * len(robots) + 2
        self.executor = MultiThreadedExecutor(num_threads=threads, context=self.context)
        self.robots: dict[str, _RobotServer] = {}
        #: Robots not served yet (they join later), served at ``start`` when they join.
        self._unserved, self._start = set(absent), start
        for name in robots:
            if name not in self._unserved:
                self._serve(name, start)
        self.thread = threading.Thread(target=self._spin, name="btcap sim ros2", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # shutting down: the context went away under the executor
            if self.context.ok():
                raise

    def _serve(self, name: str, cell: Cell) -> _RobotServer:
        robots, cell_size_m, clock, ros = self._serve_args
        node = Node(f"sim_{name}", context=self.context)
        server = self.robots[name] = _RobotServer(
            node, name, robots[name], self._manager, cell_size_m, cell, clock, ros
        )
        self.executor.add_node(node)
        return server

    def publish(self, msg: PositionUpdate) -> None:
        server = self.robots.get(msg.robot)
        if server is not None and self.context.ok():
            server.publish(msg)

    # -- a robot's servers follow its life (called on the event loop; done off it) ---------
    def withdraw(self, robot: str) -> None:
        """Take ``robot``'s servers and topics out of the ROS graph: its executions end,
        its clients see them go."""
        if not self._manager.closing.is_set():
            self._changes.submit(self._withdraw, robot)

    def serve(self, robot: str) -> None:
        """Put ``robot``'s withdrawn servers and topics back, where it was last told to be
        (a robot not served yet: its servers, at the start)."""
        if not self._manager.closing.is_set():
            self._changes.submit(self._serve_again, robot)

    def _withdraw(self, robot: str) -> None:
        server = self.robots.get(robot)
        if server is None or server.withdrawn.is_set() or not self.context.ok():
            return
        server.stop_executions(STOP_S)
        self.executor.remove_node(server.node)
        server.destroy()

    def _serve_again(self, robot: str) -> None:
        if not self.context.ok():
            return
        old = self.robots.get(robot)
        if old is None and robot in self._unserved:  # it joins for the first time
            self._unserved.discard(robot)
            self._serve(robot, self._start)
        elif old is not None and old.withdrawn.is_set():
            self._serve(robot, old.cell).served = old.served

    def served(self) -> dict[str, dict[str, int]]:
        """Goals each robot's servers took, per action."""
        return {name: dict(server.served) for name, server in self.robots.items()}

    def close(self) -> None:
        """Stop spinning, wait for the executions to end, destroy the nodes, shut the
        context down (blocks: a thread)."""
        self._manager.closing.set()
        self._changes.shutdown(wait=True)
        self.executor.shutdown(timeout_sec=5.0)
        self.thread.join(timeout=5.0)
        # rclpy 7 (Jazzy): shutdown() returns without waiting for the callbacks its pool
        # runs (and leaves the pool's threads behind): an execution still ending (it gives
        # up on `closing` within _POLL_S) would publish on a server destroyed below.
        pool = getattr(self.executor, "_executor", None)
        if pool is not None:
            pool.shutdown(wait=True)
        for robot in self.robots.values():
            if not robot.withdrawn.is_set():
                robot.destroy()
        if self.context.ok():
            rclpy.shutdown(context=self.context)
