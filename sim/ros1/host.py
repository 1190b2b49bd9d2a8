"""Robots reached through ROS 1: the in-process host, with the simulation manager served
as the paper's ROS 1 interfaces from a rospy process (:mod:`~btcap.sim.ros1.server`) and
every robot's implementations made of RosAction and RosService nodes on its own
:class:`~btcap.ros.client1.Ros1Bridge` (:mod:`~btcap.sim.ros1.steps`).

A run needs a master: the scenario's ``ros.master_uri``, else one of the run's own on a
free loopback port (:mod:`~btcap.sim.ros1.master`), stopped with it. Everything that
starts or stops a process runs in a thread, before the mission starts or after it ended.
The robots' agents still form their team, bid and run their capabilities over btcap's own
transport; what reaches their bodies goes over ROS 1.
"""

from __future__ import annotations

import asyncio
from typing import Any

import anyio

from btcap.actors import ActorRef, TimeSource
from btcap.sim.mission.capabilities import RobotSetup
from btcap.sim.mission.scenario import Scenario, check_ros_names
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros1 import ros1_missing
from btcap.sim.ros1.client import RobotLinks1
from btcap.sim.ros1.master import RunMaster, ros_env
from btcap.sim.ros1.server import Ros1SimError, SimServers1
from btcap.sim.ros2.steps import SERVER_TIMEOUT_S
from btcap.sim.rosbase.host import RosSimHost
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.model import RobotModel
from btcap.transports import MessageRegistry
from btcap.transports.log import get_logger

__all__ = ["Ros1Host", "Ros1SimError"]

log = get_logger(__name__)

#: The system the servers ask the simulation manager from.
SYSTEM_ID = "ros1-sim"


class _Started:
    """What a run started on ROS 1, closed in reverse order (a thread)."""

    def __init__(self) -> None:
        self.master: RunMaster | None = None
        self.servers: SimServers1 | None = None
        self.links: RobotLinks1 | None = None

    def close(self) -> None:
        try:
            if self.links is not None:
                self.links.close()
        finally:
            try:
                if self.servers is not None:
                    self.servers.close()
            finally:
                if self.master is not None:
                    self.master.stop()


def _start(
    started: _Started,
    loop: asyncio.AbstractEventLoop,
    manager: ActorRef[Any],
    robots: dict[str, RobotModel],
    grid: GridMap,
    clock: TimeSource,
    ros: ScenarioRos,
    absent: frozenset[str],
) -> None:
    """Start the master (unless given), serve the robots but the ``absent`` ones (they join
    later), start every robot's bridge and wait until each served robot's found its
    servers (blocks: a thread); ``started`` holds what is up."""
    uri = ros.master_uri
    if uri is None:
        started.master = RunMaster().start()
        uri = started.master.uri
        log.info("sim.ros1_master", uri=uri)
    started.servers = SimServers1(
        loop,
        manager,
        robots,
        namespaces={name: ros.namespace_of(name) for name in robots},
        cell_size_m=grid.cell_size_m,
        start=grid.start,
        clock=clock,
        master_uri=uri,
        env=ros_env(uri),
        absent=absent,
    )
    ros = _with_master(ros, uri)
    started.links = RobotLinks1(loop, robots, {name: ros.settings(name) for name in robots})
    missing = started.links.wait_for_servers(absent=absent)
    if missing:
        raise Ros1SimError(f"ROS 1: no server found for {', '.join(missing)}")


def _with_master(ros: ScenarioRos, uri: str) -> ScenarioRos:
    import msgspec

    return msgspec.structs.replace(ros, backend="ros1", master_uri=uri)


class Ros1Host(RosSimHost):
    """:class:`~btcap.sim.rosbase.host.RosSimHost` with every robot's body behind ROS 1; the
    ``manager`` is the run's simulation manager (its robots' state is published).

    Needs a real clock (ROS runs in real time): a speed-up, not a virtual clock.
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
        super().__init__(
            s, clock, reg, grid, manager=manager, backend="ROS 1", ros=ScenarioRos(backend="ros1")
        )
        self.started: _Started | None = None
        #: Goals and calls each robot's servers took, per server, once the host closed.
        self.served: dict[str, dict[str, int]] = {}
        # An operation's call may last its work and a carry: as long as the manager's asks.
        self.call_timeout_s = max(SERVER_TIMEOUT_S, clock.to_wall(3600.0) * 3 + 2.0)

    async def __aenter__(self) -> Ros1Host:
        why = ros1_missing()
        if why is not None:
            raise Ros1SimError(why)
        check_ros_names(self.s, self.ros)
        ref, robots, loop = await self._manager_side(SYSTEM_ID)
        started, absent = _Started(), frozenset(self.withdrawn)
        try:
            await anyio.to_thread.run_sync(
                _start, started, loop, ref, robots, self.grid, self.clock, self.ros, absent
            )
        except BaseException:
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(started.close)
                await self._stack.aclose()
            raise
        self.started = started
        # Closed after the robots have stopped (the stack unwinds the task group first).
        self._stack.push_async_callback(self._close)
        assert started.servers is not None
        self.manager.on_position = started.servers.publish
        await super().__aenter__()
        return self

    async def _close(self) -> None:
        self.manager.on_position = None
        started, self.started = self.started, None
        if started is not None:
            if started.servers is not None:
                self.served = started.servers.served()
                log.info("sim.ros1_served", goals=self.served)
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(started.close)

    def withdraw_servers(self, name: str) -> None:
        started = self.started
        if started is not None and started.servers is not None:
            started.servers.withdraw(name)

    def serve_servers(self, name: str) -> None:
        started = self.started
        if started is not None and started.servers is not None:
            started.servers.serve(name)

    def setup(self, name: str) -> RobotSetup:
        """The robot's implementations, their trees made of ROS 1 RosAction and RosService
        nodes on its bridge, each bidding only while the servers it calls answer."""
        from btcap.sim.ros1.steps import RosDrive1

        started = self.started
        if started is None or started.links is None:
            raise RuntimeError("Ros1Host: start robots inside `async with host`")
        link = started.links.links[name]
        drive = RosDrive1(link.bridge, self.grid.cell_size_m, self.call_timeout_s)
        return self._setup_on(name, link, drive)
