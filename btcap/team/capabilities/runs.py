"""Building and closing the implementation runs a robot executes."""

from __future__ import annotations

import asyncio
import warnings
from collections.abc import Iterable
from typing import Protocol

from btcap.actors import ActorSystem, SystemClosed, TimeSource
from btcap.errors import BtcapWarning
from btcap.team.capabilities.implementation import Implementation, ImplementationRun
from btcap.team.ids import ExecutionId
from btcap.transports.log import get_logger

__all__ = ["BUILDS_AT_ONCE", "BuildCounts", "RunFactory"]

log = get_logger(__name__)

#: Spares built in worker threads at once, per robot: :meth:`RunFactory.prepare` asks for
#: one of every implementation at the robot's start, and a thread each would take every
#: core from the event loops of a small machine (the GIL shares them anyway).
BUILDS_AT_ONCE = 1


class BuildCounts(Protocol):
    """Where the runs an award had to build on the loop are counted (the robot's
    :class:`~btcap.team.runtime.stats.MissionStats`)."""

    built_on_loop: int


class _Counts:
    built_on_loop = 0


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

    :data:`BUILDS_AT_ONCE` threads build at a time (``queued``: builds waiting for one).
    An implementation whose build fails in a thread (one that must be built on the loop's
    thread, say) is warned about once, with its error, and is built on the loop at each
    award from then on; ``stats.built_on_loop`` counts the runs built there.
    """

    def __init__(self, system: ActorSystem, stats: BuildCounts | None = None) -> None:
        self.system = system
        self.stats: BuildCounts = stats if stats is not None else _Counts()
        self._spares: dict[tuple[str, str], ImplementationRun] = {}
        self._building: set[tuple[str, str]] = set()
        self._on_loop_only: set[tuple[str, str]] = set()  # their thread build failed
        self._turns = asyncio.Semaphore(BUILDS_AT_ONCE)
        self.queued = 0  #: builds waiting for a worker thread

    @property
    def built_on_loop(self) -> int:
        """Runs an award had to build on the loop (no spare was ready)."""
        return self.stats.built_on_loop

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
            self.stats.built_on_loop += 1
            run = impl.instantiate(self.system.clock)
        asyncio.get_running_loop().call_soon(self._refill, impl)
        run.tree.name = str(execution).replace("/", ".")
        run.tree.attach(self.system)
        return run

    def _refill(self, impl: Implementation) -> None:
        key = _key(impl)
        if key in self._spares or key in self._building or not self.system.running:
            return
        if key in self._on_loop_only:
            return  # (its award builds it)
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
            self.queued += 1
            try:
                await self._turns.acquire()
            finally:
                self.queued -= 1
            try:
                run = await asyncio.to_thread(_build, impl, self.system.clock)
            finally:
                self._turns.release()
        except Exception as exc:  # its awards build it on the loop (and report their errors)
            self._on_loop_only.add(key)
            _warn_thread_build(impl, exc)
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


def _warn_thread_build(impl: Implementation, exc: Exception) -> None:
    """Once per implementation and robot (it is not built in a thread again)."""
    error = f"{type(exc).__name__}: {exc}"
    message = (
        f"implementation {impl.name!r} ({impl.interface.name}) could not be built ahead in a "
        f"worker thread ({error}): each of its awards builds it on the event loop instead, "
        "which holds the robot up while it builds; make its build work off the loop's thread"
    )
    log.warning("mission.prebuild_failed", implementation=impl.name, error=error)
    where = f"<implementation {impl.name}>"
    warnings.warn_explicit(message, BtcapWarning, where, 0, module="btcap")


def _build(impl: Implementation, clock: TimeSource) -> ImplementationRun:
    """In a worker thread: the run, and the implementation's utility (its first bid
    builds the subtree too) if not known yet."""
    impl.utility()
    return impl.instantiate(clock)


def _key(impl: Implementation) -> tuple[str, str]:
    return (impl.interface.name, impl.name)
