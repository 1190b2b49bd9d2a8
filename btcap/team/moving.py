"""Moving running work to a robot that joins (``MissionConfig.rebid_on_join``).

When the repository first learns a joining robot's capabilities, running work is
auctioned to that robot alone, costliest first, with the current bid less the margin as
reserve; the first award it accepts becomes the work's *replacement*, which the
capability node adopts on its next tick (the old run is cancelled only then, so there is
no gap and the same task never runs twice at once).
"""

from __future__ import annotations

from typing import Any, Protocol

from btcap.bt.state import State
from btcap.team.assignment import Assigned, AssignmentStrategy, AssignmentTask
from btcap.team.capability import Capability
from btcap.team.config import MissionConfig, MissionStats
from btcap.team.core.ids import ExecutionId
from btcap.team.proxies import LocalExecution, RemoteExecution
from btcap.team.repository import CapabilityRepository
from btcap.transports.log import get_logger

__all__ = ["JoinOffers"]

log = get_logger("btcap.mission")

Handle = LocalExecution | RemoteExecution


class Mover(Protocol):
    """What moving work needs from mission control."""

    robot: str
    config: MissionConfig
    stats: MissionStats
    strategy: AssignmentStrategy
    repository: CapabilityRepository
    active: dict[ExecutionId, Handle]

    def new_execution(self, node: Capability) -> ExecutionId: ...

    def remote(
        self, execution: ExecutionId, robot: str, node: Capability, cost: float
    ) -> RemoteExecution: ...

    def start_task(self, coro: Any, *, name: str | None = None) -> Any: ...


class JoinOffers:
    """Offers running work to robots as they join."""

    def __init__(self, mc: Mover) -> None:
        self.mc = mc

    def member_joined(self, robot: str) -> None:
        if self.mc.active and robot != self.mc.robot:
            self.mc.start_task(self._offer_to(robot), name=f"offer work to {robot}")

    def movable(self, ex: Handle) -> bool:
        """Running work its node holds, not being moved, and not paused (no work may start
        for a paused node)."""
        node = ex.node
        return (
            ex.id in self.mc.active
            and ex.replacement is None
            and node.execution is ex
            and node.state is not State.PAUSED
        )

    async def _offer_to(self, robot: str) -> None:
        mc = self.mc
        margin = mc.config.rebid_on_join
        assert margin is not None
        for ex in sorted(mc.active.values(), key=lambda e: (-e.cost, str(e.id))):
            node = ex.node
            iface = type(node).INTERFACE
            if (
                not self.movable(ex)
                or ex.robot == robot
                or node.options["local_only"]
                or robot not in mc.repository.providers(iface.identity)
            ):
                continue
            task = AssignmentTask(
                mc.new_execution(node),
                iface.name,
                iface.identity,
                dict(node.inputs),
                frozenset({robot}),
                mc.config.lease_s,
                reserve=ex.cost * (1.0 - margin),
                paused=True,  # it starts with the node's next inputs, as the old run stops
            )
            won = await mc.strategy.assign(task)
            if not isinstance(won, Assigned):
                continue
            new = mc.remote(task.execution, won.robot, node, won.cost)
            if not self.movable(ex):  # it ended, paused or moved while we asked
                new.cancel("no longer needed")
                continue
            ex.replacement = new
            mc.active[new.id] = new
            mc.stats.moved += 1
            log.info(
                "mission.moving",
                robot=mc.robot,
                execution=str(ex.id),
                to=robot,
                cost=won.cost,
                was=ex.cost,
            )
            return
