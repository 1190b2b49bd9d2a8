"""What the in-process hosts behind ROS 1 (:mod:`btcap.sim.ros1.host`) and ROS 2
(:mod:`btcap.sim.ros2.host`) share: the real-clock check, the system the servers ask the
simulation manager from, and a robot's implementations put on its bridge. One home, so
the two backends cannot drift apart; neither backend package imports the other for it.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

from btcap.actors import ActorRef, ActorSystem, TimeSource
from btcap.sim.mission.capabilities import Drive, RobotSetup, robot_setup
from btcap.sim.mission.scenario import Scenario
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.running.hosts import InProcessHost
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimulationManager
from btcap.sim.world.model import RobotModel
from btcap.sim.world.robot import Body
from btcap.transports import Address, MessageRegistry

__all__ = ["RosSimHost"]


class RosSimHost(InProcessHost):
    """:class:`~btcap.sim.running.hosts.InProcessHost` with every robot's body behind ROS
    (``backend``, as messages name it: ``ROS 1``, ``ROS 2``); ``manager`` is the run's
    simulation manager, ``ros`` the settings used when the scenario has no ``ros`` block.
    Needs a real clock (ROS runs in real time): a speed-up, not a virtual clock."""

    def __init__(
        self,
        s: Scenario,
        clock: TimeSource,
        reg: MessageRegistry,
        grid: GridMap,
        *,
        manager: SimulationManager,
        backend: str,
        ros: ScenarioRos,
    ) -> None:
        if not math.isfinite(clock.speedup):
            raise ValueError(
                f"robots behind {backend} run on a real clock (a speed-up), not --fast"
            )
        super().__init__(s, clock, reg, grid)
        self.manager = manager
        #: The robots' ROS settings: the scenario's ``ros`` block, else its defaults.
        self.ros = s.ros or ros
        #: Robots whose servers are out of the ROS graph: they left or failed, or have not
        #: joined yet (a robot that joins later is served from when it joins, not before).
        self.withdrawn: set[str] = {r.name for r in s.robots} - {
            r.name for r in s.initially_present()
        }

    # -- a robot's servers follow its life: a real robot that fails or leaves takes its
    # ROS side with it, and its clients (its own bids) see it go -----------------------
    def leave(self, name: str) -> None:
        super().leave(name)
        self._withdraw(name)

    def fail(self, name: str) -> None:
        super().fail(name)
        self._withdraw(name)

    def recover(self, name: str) -> None:
        self._serve(name)
        super().recover(name)

    def start(self, name: str) -> None:
        self._serve(name)
        super().start(name)

    def _withdraw(self, name: str) -> None:
        if name not in self.withdrawn:
            self.withdrawn.add(name)
            self.withdraw_servers(name)

    def _serve(self, name: str) -> None:
        if name in self.withdrawn:
            self.withdrawn.discard(name)
            self.serve_servers(name)

    def withdraw_servers(self, name: str) -> None:
        """Take robot ``name``'s servers and topics out of the ROS graph (on the loop: at
        most a short write; the backend does the rest off it)."""
        raise NotImplementedError

    def serve_servers(self, name: str) -> None:
        """Put robot ``name``'s withdrawn servers and topics back (as :meth:`withdraw_servers`)."""
        raise NotImplementedError

    async def _manager_side(
        self, system_id: str
    ) -> tuple[ActorRef[Any], dict[str, RobotModel], asyncio.AbstractEventLoop]:
        """Enter the system ``system_id`` the servers ask the manager from (closed with
        the host); the manager's ref from it, the robots' models by name, the loop."""
        system = ActorSystem(
            system_id, transport=self.net.transport(system_id), registry=self.reg, clock=self.clock
        )
        await self._stack.enter_async_context(system)
        ref = system.ref(Address.parse("sim/manager"))
        robots = {r.name: self.models[r.model] for r in self.s.robots}
        return ref, robots, asyncio.get_running_loop()

    def _setup_on(self, name: str, link: Any, drive: Drive) -> RobotSetup:
        """Robot ``name``'s implementations on ``link.bridge`` with ``drive``, each bidding
        only while the servers it calls answer (:func:`~btcap.ros.capability.with_ros`);
        its body is told to ``link`` (its state subscription)."""
        from btcap.ros.capability import with_ros

        model = next(r.model for r in self.s.robots if r.name == name)
        setup = robot_setup(name, self.models[model], self.grid, drive=drive, bids=self.s.bids)
        setup.implementations = [with_ros(i, link.bridge) for i in setup.implementations]
        link.body = setup.actors[Body.PATH]
        return setup
