"""The draws an operation on an object gets, known before the run: the simulation draws
each operation's duration factor and failure from a stream keyed by the seed, what the
operation is and how many attempts at it ran to their end
(:meth:`~btcap.sim.world.manager.SimulationManager.draw`), not by who does it or when.
So every run of a seed identifies object 3 with the same first draw, and the bound
(:mod:`btcap.sim.mission.bound`) can price an operation by it instead of the shortest.
"""

from __future__ import annotations

from btcap.sim.world.manager import SimConfig, SimulationManager
from btcap.sim.world.store import MissionState

__all__ = ["Draws", "least_factor"]


class Draws:
    """The draws of the simulation a run of ``state`` (its objects) and ``config`` (its
    seed, jitter and failure chance) makes: asked of a manager never started."""

    def __init__(self, state: MissionState, config: SimConfig) -> None:
        self.config = config
        self._manager = SimulationManager(state, config)

    def factor(self, op: str, target: int) -> float:
        """The least factor (of its model's duration) that all attempts at ``op`` on
        object ``target`` add up to before one succeeds, in any run.

        The first attempt to end drew the stream's first draw (every attempt started
        before any ended draws it); if that draw fails, the one that succeeds started
        after it ended, drew a later one and took at least the shortest factor. Attempts
        cut short draw again and only add time.
        """
        first, fails = self._manager.draw(op, target, (0, 0))
        return first + (1 - self.config.delay_jitter) if fails else first


def least_factor(draws: Draws | None, jitter: float, op: str, target: int) -> float:
    """:meth:`Draws.factor` if the draws are known, else the shortest draw."""
    return draws.factor(op, target) if draws is not None else 1 - jitter
