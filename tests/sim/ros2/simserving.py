"""The simulated robots' ROS 2 servers for a test: a simulation manager on an actor system
of its own, served by :class:`~btcap.sim.ros2.server.SimServers` (made in a thread: it
starts rclpy) until the block ends, then closed (nodes and action servers destroyed)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

import anyio

from btcap.actors import ActorSystem, TimeSource
from btcap.sim.running.hosts import registry
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.model import RobotModel
from btcap.transports import Address, InProcessNetwork


@asynccontextmanager
async def serving(
    manager: SimulationManager,
    robots: dict[str, RobotModel],
    grid: GridMap,
    clock: TimeSource,
    **options: Any,
) -> AsyncIterator[Any]:
    """``manager``'s ``robots`` served (``options``: SimServers' ``domain_id``, ``ros``);
    its positions published while the block runs."""
    from btcap.sim.ros2.server import SimServers

    reg = registry()
    net = InProcessNetwork(reg)
    async with ActorSystem("sim", transport=net.transport("sim"), registry=reg, clock=clock) as sim:
        sim.spawn(manager, SimulationManager.PATH)
        loop = asyncio.get_running_loop()
        servers = await anyio.to_thread.run_sync(
            lambda: SimServers(
                loop,
                sim.ref(Address.parse(f"sim/{SimulationManager.PATH}")),
                robots,
                cell_size_m=grid.cell_size_m,
                start=grid.start,
                clock=clock,
                **options,
            )
        )
        manager.on_position = servers.publish
        try:
            yield servers
        finally:
            manager.on_position = None
            with anyio.CancelScope(shield=True):
                await anyio.to_thread.run_sync(servers.close)
