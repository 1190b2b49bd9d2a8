"""A robot's side of the simulator behind ROS 2: action clients for its navigation and its
operations and a subscription to its state, awaited from the mission's event loop.

Each robot has a :class:`~btcap.ros.client.RosBridge` of its own (the ROS 2 bridge's
client: one rclpy node ``/<robot>/btcap``, its own context and DDS participant, an executor
thread, goals still open cancelled when it closes), as a real robot's agent does. Its
callbacks run on that thread and hand everything to the event loop; a coroutine cancelled
while its goal runs cancels the goal (the servers then stop the robot). Imports rclpy:
loaded in a thread by :mod:`btcap.sim.ros2.host`.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
from typing import Any

from action_msgs.msg import GoalStatus
from btcap_sim_msgs.action import NavigateToPose
from btcap_sim_msgs.action import Operate as OperateAction
from btcap_sim_msgs.msg import RobotState
from rclpy.task import Future

from btcap.actors import Actor
from btcap.ros.client import RosBridge
from btcap.sim.distance import Cell
from btcap.sim.messages import PositionUpdate, SimResult
from btcap.sim.model import RobotModel
from btcap.sim.ros2.names import NAVIGATE_TYPE, OPERATE_TYPE, OPERATIONS, RobotNames
from btcap.sim.ros2.server import pose_at
from btcap.team.rossettings import RosSettings

__all__ = ["RobotLink", "RobotLinks"]

#: Wall seconds to wait for a robot's servers to be discovered before the mission starts.
DISCOVERY_S = 30.0


async def _awaited(fut: Future, loop: asyncio.AbstractEventLoop) -> Any:
    """An rclpy future, awaited on the event loop (its callback runs on the ROS thread)."""
    done: asyncio.Future[Any] = loop.create_future()

    def settle(f: Future) -> None:
        def set_it() -> None:
            if done.done():
                return
            exc = f.exception()
            if exc is not None:
                done.set_exception(exc)
            else:
                done.set_result(f.result())

        loop.call_soon_threadsafe(set_it)

    fut.add_done_callback(settle)
    return await done


class RobotLink:
    """One robot's clients, on its bridge: :meth:`navigate` and :meth:`operate` answer as
    the manager's asks do (a :class:`~btcap.sim.messages.SimResult`); every state the robot
    publishes is told to ``body`` (its :class:`~btcap.sim.robot.Body`, once spawned)."""

    def __init__(
        self,
        bridge: RosBridge,
        robot: str,
        model: RobotModel,
        loop: asyncio.AbstractEventLoop,
        cell_size_m: float,
    ) -> None:
        self.bridge = bridge
        self.robot = robot
        self.loop = loop
        self.cell_size_m = cell_size_m
        self.body: Actor | None = None
        names = RobotNames(robot)
        # Names relative to the bridge's namespace (/<robot>), as a real robot's file has them.
        self.nav = bridge.action_client(NAVIGATE_TYPE, "navigate_to_pose")
        self.ops = {
            op: bridge.action_client(OPERATE_TYPE, op) for op in OPERATIONS if model.can(op)
        }
        self.cell: Cell | None = None
        bridge.running().create_subscription(RobotState, names.state, self._on_state, bridge.qos())

    def wait_for_servers(self, timeout_s: float) -> list[str]:
        """Wait for the robot's action servers (a thread); the names of those not found."""
        missing = []
        for client in (self.nav, *self.ops.values()):
            if not client.wait_for_server(timeout_sec=timeout_s):
                missing.append(client._action_name)
        return missing

    def _on_state(self, msg: Any) -> None:
        update = PositionUpdate(
            self.robot, (int(msg.row), int(msg.col)), msg.operation, int(msg.target), msg.phase
        )
        self.loop.call_soon_threadsafe(self._tell_body, update)

    def _tell_body(self, update: PositionUpdate) -> None:
        self.cell = update.position
        body = self.body
        if body is not None and body._system is not None:
            body.ref.tell(update)

    async def _run(self, client: Any, goal: Any) -> tuple[bool, Any]:
        """Send ``goal``; (whether it succeeded, its result). Cancelled: the goal is too."""
        handle = await _awaited(client.send_goal_async(goal), self.loop)
        if not handle.accepted:
            return False, None
        self.bridge.track(handle)  # cancelled if the bridge closes while it runs
        try:
            got = await _awaited(handle.get_result_async(), self.loop)
        except asyncio.CancelledError:
            handle.cancel_goal_async()
            raise
        finally:
            self.bridge.untrack(handle)
        return got.status == GoalStatus.STATUS_SUCCEEDED, got.result

    def _here(self) -> tuple[int, int]:
        return self.cell if self.cell is not None else (0, 0)

    async def navigate(self, goal: Cell) -> SimResult:
        """Drive to ``goal``: the navigation action, its pose in the map frame."""
        request = NavigateToPose.Goal()
        request.pose = pose_at(goal, self.cell_size_m, 0.0)
        ok, result = await self._run(self.nav, request)
        if result is None:
            return SimResult(False, self._here(), "navigation goal rejected")
        if not ok:
            return SimResult(False, self._here(), result.error_msg or "navigation failed")
        return SimResult(True, goal)

    async def operate(self, op: str, target: int) -> SimResult:
        """``op`` on object ``target`` (-1 for none): the robot's action of that name."""
        client = self.ops.get(op)
        if client is None:
            return SimResult(False, self._here(), f"{self.robot} offers no {op} action")
        ok, result = await self._run(client, OperateAction.Goal(target=target))
        if result is None:
            return SimResult(False, self._here(), f"{op} goal rejected")
        found, dirty = int(result.found), bool(result.contaminated)
        return SimResult(ok and result.ok, self._here(), result.detail, found, dirty)


class RobotLinks:
    """The robots' side: a started :class:`~btcap.ros.client.RosBridge` per robot (its
    node in its namespace) and the robot's clients on it, until :meth:`close`.

    Made in a thread (it imports and starts rclpy)."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        robots: dict[str, RobotModel],
        *,
        cell_size_m: float,
        domain_id: int | None = None,
    ) -> None:
        self.bridges = {
            name: RosBridge(RosSettings(domain_id=domain_id), robot=name) for name in robots
        }
        self.links: dict[str, RobotLink] = {}
        try:
            # Each start watches the graph for a twin of its node for a while: all at once.
            workers = min(len(robots), 16)
            with concurrent.futures.ThreadPoolExecutor(workers, "btcap robot ros2") as pool:
                list(pool.map(RosBridge.start, self.bridges.values()))  # raises the first error
            for name, model in robots.items():
                self.links[name] = RobotLink(self.bridges[name], name, model, loop, cell_size_m)
        except BaseException:
            self.close()
            raise

    def wait_for_servers(self, timeout_s: float = DISCOVERY_S) -> list[str]:
        """Every robot's action servers found (a thread); the names of those not found."""
        return [m for link in self.links.values() for m in link.wait_for_servers(timeout_s)]

    def close(self) -> None:
        """Close every robot's bridge: open goals cancelled, nodes destroyed, threads
        joined (blocks: a thread)."""
        for bridge in self.bridges.values():
            bridge.close()
