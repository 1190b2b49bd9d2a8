"""Building and closing the implementation runs a robot executes."""

from __future__ import annotations

import asyncio
from collections.abc import Iterable

from btcap.actors import ActorSystem, SystemClosed, TimeSource
from btcap.team.capabilities.implementation import Implementation, ImplementationRun
from btcap.team.ids import ExecutionId
from btcap.transports.log import get_logger

__all__ = ["RunFactory"]

log = get_logger(__name__)


class RunFactory:
    """Fresh runs for awards, one built ahead per implementation (building a subtree costs
    more than the rest of an award), attached to the robot's system at a path unique to
    the execution so its nodes are actors of this robot.

    Building is CPU work that grows with the subtree (a file-backed implementation also
    reads and parses its file: ~40 ms for 300 nodes, ~300 ms for 2000), so on a real
    clock the spares are built in a worker thread, from :meth:`prepare` on (the robot's
    start) and again after every award; an award builds on the loop only when two come
    faster than a spare. On a virtual clock (``--fast``) they are built on the loop, as
    the run must not depend on when a thread finishes.
    """

    def __init__(self, system: ActorSystem) -> None:
        self.system = system
        self._spares: dict[tuple[str, str], ImplementationRun] = {}
        self._building: set[tuple[str, str]] = set()
        #: Runs an award had to build on the loop (no spare was ready).
        self.built_on_loop = 0

    def ready(self, impl: Implementation) -> bool:
        """Whether a run of ``impl`` is built ahead, so its next award takes no build."""
        return _key(impl) in self._spares

    @property
    def _threads(self) -> bool:
        return self.system.clock.to_wall(1.0) > 0.0  # a real clock (virtual: 0)

    def prepare(self, impls: Iterable[Implementation]) -> None:
        """Build a spare of each of ``impls`` ahead of its first award (real clock only)."""
        if self._threads:
            for impl in impls:
                self._refill(impl)

    def take(self, impl: Implementation, execution: ExecutionId) -> ImplementationRun:
        run = self._spares.pop(_key(impl), None)
        if run is None:
            self.built_on_loop += 1
            run = impl.instantiate(self.system.clock)
        asyncio.get_running_loop().call_soon(self._refill, impl)
        run.tree.name = str(execution).replace("/", ".")
        run.tree.attach(self.system)
        return run

    def _refill(self, impl: Implementation) -> None:
        key = _key(impl)
        if key in self._spares or key in self._building or not self.system.running:
            return
        if self._threads:
            self._building.add(key)
            try:
                self.system.start_task(self._build_off_loop(impl), name=f"build {impl.name}")
            except SystemClosed:
                self._building.discard(key)
            return
        try:
            self._spares[key] = impl.instantiate(self.system.clock)
        except Exception as exc:  # the award path reports it with context
            log.debug("mission.prebuild_failed", implementation=impl.name, error=str(exc))

    async def _build_off_loop(self, impl: Implementation) -> None:
        key = _key(impl)
        try:
            run = await asyncio.to_thread(_build, impl, self.system.clock)
        except Exception as exc:  # the award path builds it again, and reports it with context
            log.debug("mission.prebuild_failed", implementation=impl.name, error=str(exc))
            return
        finally:
            self._building.discard(key)
        if key not in self._spares and self.system.running:
            self._spares[key] = run

    def close(self, run: ImplementationRun) -> None:
        """Shut the nodes down at once, so nothing of the run works on (also while the
        system stops and no task can run); a system task then removes its actors."""
        run.tree.root.shutdown()
        if self.system.running:
            self.system.start_task(run.close(), name=f"close {run.tree.name}")


def _build(impl: Implementation, clock: TimeSource) -> ImplementationRun:
    """In a worker thread: the run, and the implementation's utility (its first bid
    builds the subtree too) if not known yet."""
    impl.utility()
    return impl.instantiate(clock)


def _key(impl: Implementation) -> tuple[str, str]:
    return (impl.interface.name, impl.name)
