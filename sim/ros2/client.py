"""A robot's side of the simulator behind ROS 2: its :class:`~btcap.ros.client.RosBridge`
(the bridge a real robot's agent runs: one rclpy node in its namespace, its own context and
DDS participant, an executor thread, open goals cancelled when it closes), the action
clients its implementations' RosAction nodes share, found before the mission starts, and a
subscription to its state that keeps its :class:`~btcap.sim.world.robot.Body` (what its bids
start from) where the simulation says it is.

Its capabilities reach the simulation only through those RosAction nodes
(:mod:`btcap.sim.ros2.steps`). Imports rclpy: loaded in a thread by
:mod:`btcap.sim.ros2.host`.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
from collections.abc import Collection

from btcap_sim_msgs.msg import RobotState

from btcap.ros.client import RosBridge
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros2.names import NAVIGATE_TYPE, OPERATE_TYPE, OPERATIONS
from btcap.sim.rosbase.state import StateLink, close_bridges
from btcap.sim.world.model import RobotModel
from btcap.team.rossettings import Qos

__all__ = ["RobotLink", "RobotLinks"]

#: Wall seconds to wait for a robot's servers to be discovered before the mission starts.
DISCOVERY_S = 30.0
#: The state topic carries every cell and phase: reliable, and a history deep enough that
#: a burst is not lost.
STATE_QOS = Qos(depth=100)


class RobotLink(StateLink):
    """One robot's bridge, its action clients, and its state told to ``body`` (its
    :class:`~btcap.sim.world.robot.Body`, once spawned)."""

    def __init__(
        self, bridge: RosBridge, robot: str, model: RobotModel, loop: asyncio.AbstractEventLoop
    ) -> None:
        super().__init__(robot, loop)
        self.bridge = bridge
        # Names relative to the bridge's namespace, as a real robot's files have them; the
        # RosAction nodes of its implementations use these clients (the bridge shares them).
        self.clients = [bridge.action_client(NAVIGATE_TYPE, "navigate_to_pose")]
        ops = [op for op in OPERATIONS if model.can(op)]
        self.clients += [bridge.action_client(OPERATE_TYPE, op) for op in ops]
        bridge.running().create_subscription(
            RobotState, bridge.resolve("state"), self._on_state, bridge.qos(STATE_QOS)
        )

    def wait_for_servers(self, timeout_s: float) -> list[str]:
        """Wait for the robot's action servers (a thread); the names of those not found."""
        missing = []
        for client in self.clients:
            if not client.wait_for_server(timeout_sec=timeout_s):
                missing.append(client._action_name)
        return missing


class RobotLinks:
    """The robots' side: a started :class:`~btcap.ros.client.RosBridge` per robot (its
    node in its namespace, from ``ros``) and the robot's link on it, until :meth:`close`.

    Made in a thread (it imports and starts rclpy)."""

    def __init__(
        self, loop: asyncio.AbstractEventLoop, robots: dict[str, RobotModel], ros: ScenarioRos
    ) -> None:
        self.bridges = {name: RosBridge(ros.settings(name), robot=name) for name in robots}
        self.links: dict[str, RobotLink] = {}
        try:
            # Each start watches the graph for a twin of its node for a while: all at once.
            workers = min(len(robots), 16)
            with concurrent.futures.ThreadPoolExecutor(workers, "btcap robot ros2") as pool:
                list(pool.map(RosBridge.start, self.bridges.values()))  # raises the first error
            for name, model in robots.items():
                self.links[name] = RobotLink(self.bridges[name], name, model, loop)
        except BaseException:
            self.close()
            raise

    def wait_for_servers(
        self, timeout_s: float = DISCOVERY_S, *, absent: Collection[str] = ()
    ) -> list[str]:
        """Every robot's action servers found but ``absent`` robots' (not served yet: they
        join later) (a thread); the names of those not found."""
        links = [link for name, link in self.links.items() if name not in absent]
        return [m for link in links for m in link.wait_for_servers(timeout_s)]

    def close(self) -> None:
        """Close every robot's bridge, all at once (each waits up to CLOSE_WAIT_S for its
        servers to answer its cancels): open goals cancelled, nodes destroyed, threads
        joined (blocks: a thread)."""
        close_bridges(self.bridges.values())
