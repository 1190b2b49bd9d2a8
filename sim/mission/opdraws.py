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

__all__ = ["Draws", "least_factors"]


class Draws:
    """The draws of the simulation a run of ``state`` (its objects) and ``config`` (its
    seed, jitter and failure chance) makes: asked of a manager never started."""

    def __init__(self, state: MissionState, config: SimConfig) -> None:
        self.config = config
        self._manager = SimulationManager(state, config)

    def factors(self, op: str, target: int) -> tuple[float, float]:
        """The factors (of a model's duration) of ``op`` on object ``target`` in any
        run: the first attempt to end, and at least what follows until one succeeds.

        Every attempt started before any ended draws the stream's first draw, so the
        first to end took that factor, and failed if it fails; then the one that
        succeeds started after it ended, drew a later one and took at least the
        shortest factor. Attempts cut short draw again and only add time.
        """
        first, fails = self._manager.draw(op, target, (0, 0))
        return first, (1 - self.config.delay_jitter) if fails else 0.0

    def attempts(
        self, op: str, target: int, most: int = 50, cell: tuple[int, int] = (0, 0)
    ) -> list[float]:
        """The factors of every attempt at ``op`` on object ``target`` (explore: at
        ``cell``) run to its end until one succeeds (``most`` at most): what one robot
        doing it again and again until it succeeds spends, as multiples of its model's
        duration."""
        out = []
        for n in range(most):
            factor, fails = self._manager.draw(op, target, cell, attempt=n)
            out.append(factor)
            if not fails:
                break
        return out


def least_factors(draws: Draws | None, jitter: float, op: str, target: int) -> tuple[float, float]:
    """:meth:`Draws.factors` if the draws are known, else the shortest draw and nothing."""
    return draws.factors(op, target) if draws is not None else (1 - jitter, 0.0)
