"""``btcap sim serve``: the simulated world on its own, every robot behind ROS 2, for robots
whose agents run elsewhere (``btcap agent`` with a ``ros:`` block, one process each), the
shape of a real deployment: the simulation plays the robots' ROS side (their navigation
action, operations, pose and state topics, stop service, in their namespaces), and the
agents reach it only through ROS 2, as they would reach a real robot's servers.

Nothing of the mission runs here: no team, no mission tree, no object store. Whoever runs
a mission (``btcap mission run``) gives the agents their goals; the world answers the
robots' goals until it is stopped. rclpy is loaded in a thread once serving starts.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import anyio
import numpy as np

from btcap.actors import ActorSystem, Clock
from btcap.sim.mission.scenario import Scenario, check_ros_names, check_scenario
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros2 import ros2_missing
from btcap.sim.ros2.host import Ros2Unavailable
from btcap.sim.running.hosts import registry
from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.messages import PositionUpdate
from btcap.sim.world.model import RobotModel
from btcap.sim.world.store import MissionState
from btcap.transports import Address, InProcessNetwork
from btcap.transports.log import get_logger

if TYPE_CHECKING:
    from btcap.sim.ros2.server import SimServers

__all__ = ["POSE_EVERY_S", "Served", "serve"]

log = get_logger(__name__)

#: Wall seconds between two publications of every robot's pose while it stands still, so
#: an agent that starts late (a distance bid reads the pose topic) hears where it is.
POSE_EVERY_S = 1.0

#: Goals each robot's servers took, per action: ``{"husky1": {"navigate_to_pose": 2}}``.
Served = dict[str, dict[str, int]]


def _serve(
    loop: asyncio.AbstractEventLoop,
    manager: Any,
    robots: dict[str, RobotModel],
    s: Scenario,
    clock: Clock,
    ros: ScenarioRos,
) -> SimServers:
    from btcap.ros.loader import load

    load()
    from btcap.sim.ros2.server import SimServers

    grid = s.grid()
    return SimServers(
        loop, manager, robots, cell_size_m=grid.cell_size_m, start=grid.start, clock=clock, ros=ros
    )


async def serve(
    s: Scenario,
    *,
    stop: anyio.Event,
    ready: Callable[[dict[str, str]], None] | None = None,
) -> Served:
    """Serve ``s``'s world and robots behind ROS 2 (its ``ros`` block, else its defaults)
    until ``stop`` is set; ``ready`` is told each robot's namespace once every server is
    up. Returns the goals served. Ros2Unavailable when ROS 2 or the interfaces are
    missing; ScenarioError for a robot name that makes no namespace."""
    s = check_scenario(s)
    ros = s.ros or ScenarioRos()
    check_ros_names(s, ros)
    if (why := ros2_missing()) is not None:
        raise Ros2Unavailable(why)
    if not math.isfinite(s.speedup):
        raise ValueError("the served world runs on the wall clock: a finite speed-up")
    clock = Clock(s.speedup)
    reg = registry()
    grid = s.grid()
    state = MissionState.scatter(
        grid, s.objects, s.contaminated_share, np.random.default_rng(s.seed)
    )
    manager = SimulationManager(
        state, SimConfig(s.sim.step_s, s.sim.delay_jitter, s.sim.failure_chance, s.seed)
    )
    models = s.models()
    robots = {r.name: models[r.model] for r in s.robots}
    for name, model in robots.items():
        manager.add_robot(name, model)
        manager.robot_up(name)
    net = InProcessNetwork(reg)
    async with ActorSystem("sim", transport=net.transport("sim"), registry=reg, clock=clock) as sim:
        sim.spawn(manager, SimulationManager.PATH)
        ref = sim.ref(Address.parse(f"sim/{SimulationManager.PATH}"))
        loop = asyncio.get_running_loop()
        servers = await anyio.to_thread.run_sync(_serve, loop, ref, robots, s, clock, ros)
        manager.on_position = servers.publish
        try:
            if ready is not None:
                ready({name: ros.namespace_of(name) for name in robots})
            while not stop.is_set():
                for name in robots:  # where each robot stands, for late subscribers
                    servers.publish(PositionUpdate(name, manager.position(name)))
                with anyio.move_on_after(POSE_EVERY_S):
                    await stop.wait()
        finally:
            manager.on_position = None
            served = servers.served()
            log.info("sim.ros2_served", goals=served)
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(servers.close)
    return served
