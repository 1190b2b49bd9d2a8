"""A robot's side of the simulator behind ROS 1: its :class:`~btcap.ros.client1.Ros1Bridge`
(the bridge a real ROS 1 robot's agent runs: a rospy node in its namespace, in a process of
its own), the clients its implementations' RosAction and RosService nodes share, found
before the mission starts, and a subscription to its ``state`` topic that keeps its
:class:`~btcap.sim.world.robot.Body` (what its bids start from) where the simulation says it is.

Starting and closing block (a thread): :mod:`btcap.sim.ros1.host` calls them off the loop.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import time
from collections.abc import Collection

from btcap.ros.client1 import Ros1Bridge
from btcap.ros.interfaces1 import interface1
from btcap.sim.ros1.names1 import MOVE_BASE, MOVE_BASE_TYPE, OPERATE_TYPE, STATE_TYPE
from btcap.sim.ros2.names import OPERATIONS
from btcap.sim.rosbase.state import StateLink, close_bridges
from btcap.sim.world.model import RobotModel
from btcap.team.rossettings import RosSettings

__all__ = ["RobotLink1", "RobotLinks1"]

#: Wall seconds to wait for a robot's servers before the mission starts (a bound).
DISCOVERY_S = 30.0
_POLL_S = 0.05


class RobotLink1(StateLink):
    """One robot's bridge, its clients, and its state told to ``body`` once spawned."""

    def __init__(
        self, bridge: Ros1Bridge, robot: str, model: RobotModel, loop: asyncio.AbstractEventLoop
    ) -> None:
        super().__init__(robot, loop)
        self.bridge = bridge
        self.servers = [("action", MOVE_BASE_TYPE, MOVE_BASE)]
        self.servers += [("service", OPERATE_TYPE, op) for op in OPERATIONS if model.can(op)]
        for kind, type_name, name in self.servers:  # opened now: found by the time we run
            self.bridge.server_ready(kind, type_name, name)
        state = interface1(STATE_TYPE, "msg")
        bridge.running().create_subscription(state, "state", self._on_state, (100, False))

    def missing(self) -> list[str]:
        return [
            self.bridge.resolve(name)
            for kind, type_name, name in self.servers
            if not self.bridge.server_ready(kind, type_name, name)
        ]


class RobotLinks1:
    """A started :class:`~btcap.ros.client1.Ros1Bridge` per robot and its link, until
    :meth:`close` (made in a thread: each bridge starts a process)."""

    def __init__(
        self,
        loop: asyncio.AbstractEventLoop,
        robots: dict[str, RobotModel],
        settings: dict[str, RosSettings],
    ) -> None:
        self.bridges = {name: Ros1Bridge(settings[name], robot=name) for name in robots}
        self.links: dict[str, RobotLink1] = {}
        try:
            workers = min(len(robots), 16)
            with concurrent.futures.ThreadPoolExecutor(workers, "btcap robot ros1") as pool:
                list(pool.map(Ros1Bridge.start, self.bridges.values()))
            for name, model in robots.items():
                self.links[name] = RobotLink1(self.bridges[name], name, model, loop)
        except BaseException:
            self.close()
            raise

    def wait_for_servers(
        self, timeout_s: float = DISCOVERY_S, *, absent: Collection[str] = ()
    ) -> list[str]:
        """Wait until every robot's servers are ready but ``absent`` robots' (not served
        yet: they join later) (a thread); the names of those not."""
        links = [link for name, link in self.links.items() if name not in absent]
        deadline = time.monotonic() + timeout_s
        while True:
            missing = [m for link in links for m in link.missing()]
            if not missing or time.monotonic() > deadline:
                return missing
            time.sleep(_POLL_S)

    def close(self) -> None:
        """Close every bridge, all at once: goals cancelled, the rospy processes gone (a
        thread)."""
        close_bridges(self.bridges.values())
