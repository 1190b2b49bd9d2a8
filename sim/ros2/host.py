"""Robots reached through ROS 2: the in-process host, with the simulation manager served as
ROS 2 interfaces (:mod:`~btcap.sim.ros2.server`) and every robot's implementations made of
RosAction nodes on its own bridge (:mod:`~btcap.sim.ros2.steps`,
:mod:`~btcap.sim.ros2.client`).

rclpy is imported and started in a thread as the host is entered, before the mission
starts, so the event loop never waits on it, and only when asked for (``btcap run --ros2``):
``btcap --help`` and every other run never load it. The robots' agents still form their
team, bid and run their capabilities over btcap's own transport, as in-process robots do;
what reaches their bodies (drive, explore, identify, decontaminate, where they are) goes over
DDS, in the domain, namespaces and QoS of the scenario's ``ros`` block (its defaults: the
``ROS_DOMAIN_ID`` of the environment, ``/<robot>``).
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

import anyio

from btcap.actors import ActorRef, TimeSource
from btcap.errors import BtcapError
from btcap.sim.mission.capabilities import RobotSetup
from btcap.sim.mission.scenario import Scenario, check_ros_names
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros2 import ros2_missing
from btcap.sim.rosbase.host import RosSimHost
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.model import RobotModel
from btcap.transports import MessageRegistry
from btcap.transports.log import get_logger

if TYPE_CHECKING:
    from btcap.sim.ros2.client import RobotLinks
    from btcap.sim.ros2.server import SimServers

__all__ = ["Ros2Host", "Ros2Unavailable"]

log = get_logger(__name__)

#: The system the servers ask the simulation manager from.
SYSTEM_ID = "ros2-sim"


class Ros2Unavailable(BtcapError, RuntimeError):
    """ROS 2 or the simulated robots' interfaces are not installed here."""


def _start(
    loop: asyncio.AbstractEventLoop,
    manager: ActorRef[Any],
    robots: dict[str, RobotModel],
    grid: GridMap,
    clock: TimeSource,
    ros: ScenarioRos,
    absent: frozenset[str],
) -> tuple[SimServers, RobotLinks]:
    """Import rclpy, serve the robots but the ``absent`` ones (they join later), connect
    every robot's clients and wait until each served robot's found its servers (blocks: a
    thread)."""
    from btcap.ros.loader import load

    load()  # rclpy, with the wheels' import-time warnings silenced (btcap.ros.loader)
    from btcap.sim.ros2.client import RobotLinks
    from btcap.sim.ros2.server import SimServers

    size = grid.cell_size_m
    servers = SimServers(
        loop,
        manager,
        robots,
        cell_size_m=size,
        start=grid.start,
        clock=clock,
        ros=ros,
        absent=absent,
    )
    try:
        links = RobotLinks(loop, robots, ros)
    except BaseException:
        servers.close()
        raise
    try:
        missing = links.wait_for_servers(absent=absent)
    except BaseException:
        _close(servers, links)
        raise
    if missing:
        _close(servers, links)
        raise Ros2Unavailable(f"ROS 2: no server found for {', '.join(missing)}")
    return servers, links


def _close(servers: SimServers, links: RobotLinks) -> None:
    try:
        links.close()
    finally:
        servers.close()


class Ros2Host(RosSimHost):
    """:class:`~btcap.sim.rosbase.host.RosSimHost` with every robot's body behind ROS 2; the
    ``manager`` is the run's simulation manager (its robots' state is published, not told).

    Needs a real clock (DDS runs in real time): a speed-up, not a virtual clock.
    """

    def __init__(
        self,
        s: Scenario,
        clock: TimeSource,
        reg: MessageRegistry,
        grid: GridMap,
        *,
        manager: SimulationManager,
    ) -> None:
        super().__init__(s, clock, reg, grid, manager=manager, backend="ROS 2", ros=ScenarioRos())
        self.servers: SimServers | None = None
        self.links: RobotLinks | None = None

    async def __aenter__(self) -> Ros2Host:
        why = ros2_missing()
        if why is not None:
            raise Ros2Unavailable(why)
        check_ros_names(self.s, self.ros)
        ref, robots, loop = await self._manager_side(SYSTEM_ID)
        absent = frozenset(self.withdrawn)
        try:
            servers, self.links = await anyio.to_thread.run_sync(
                _start, loop, ref, robots, self.grid, self.clock, self.ros, absent
            )
        except BaseException:
            await self._stack.aclose()
            raise
        self.servers = servers
        # Closed after the robots have stopped (the stack unwinds the task group first).
        self._stack.push_async_callback(self._close)
        self.manager.on_position = servers.publish
        await super().__aenter__()
        return self

    async def _close(self) -> None:
        self.manager.on_position = None
        servers, links = self.servers, self.links
        self.servers = self.links = None
        if servers is not None and links is not None:
            log.info("sim.ros2_served", goals=servers.served())
            await anyio.to_thread.run_sync(_close, servers, links)

    def withdraw_servers(self, name: str) -> None:
        if self.servers is not None:
            self.servers.withdraw(name)

    def serve_servers(self, name: str) -> None:
        if self.servers is not None:
            self.servers.serve(name)

    def setup(self, name: str) -> RobotSetup:
        """The robot's implementations, their trees made of RosAction nodes on its bridge
        (:mod:`btcap.sim.ros2.steps`), each bidding only while the servers it calls are in
        the ROS graph (:func:`~btcap.ros.capability.with_ros`)."""
        from btcap.sim.ros2.steps import RosDrive

        if self.links is None:
            raise RuntimeError("Ros2Host: start robots inside `async with host`")
        link = self.links.links[name]
        return self._setup_on(name, link, RosDrive(link.bridge, self.grid.cell_size_m))
