"""Building and closing the implementation runs a robot executes."""

from __future__ import annotations

import asyncio

from btcap.actors import ActorSystem
from btcap.team.capabilities.implementation import Implementation, ImplementationRun
from btcap.team.ids import ExecutionId
from btcap.transports.log import get_logger

__all__ = ["RunFactory"]

log = get_logger(__name__)


class RunFactory:
    """Fresh runs for awards, one built ahead per implementation (building a subtree costs
    more than the rest of an award), attached to the robot's system at a path unique to
    the execution so its nodes are actors of this robot."""

    def __init__(self, system: ActorSystem) -> None:
        self.system = system
        self._spares: dict[tuple[str, str], ImplementationRun] = {}

    def take(self, impl: Implementation, execution: ExecutionId) -> ImplementationRun:
        run = self._spares.pop(_key(impl), None)
        if run is None:
            run = impl.instantiate(self.system.clock)
        asyncio.get_running_loop().call_soon(self._refill, impl)
        run.tree.name = str(execution).replace("/", ".")
        run.tree.attach(self.system)
        return run

    def _refill(self, impl: Implementation) -> None:
        if _key(impl) in self._spares or not self.system.running:
            return
        try:
            self._spares[_key(impl)] = impl.instantiate(self.system.clock)
        except Exception as exc:  # the award path reports it with context
            log.debug("mission.prebuild_failed", implementation=impl.name, error=str(exc))

    def close(self, run: ImplementationRun) -> None:
        """Shut the nodes down at once, so nothing of the run works on (also while the
        system stops and no task can run); a system task then removes its actors."""
        run.tree.root.shutdown()
        if self.system.running:
            self.system.start_task(run.close(), name=f"close {run.tree.name}")


def _key(impl: Implementation) -> tuple[str, str]:
    return (impl.interface.name, impl.name)
