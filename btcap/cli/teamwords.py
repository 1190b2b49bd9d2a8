"""What the team commands say about joining and departing, in a person's words: whether
a robot ever joined its team and if not why (on a signal, or when the seeds stay
silent), and which robots failed or left lately (``btcap team status``).

Imported by a command once it runs (it loads the team layer)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from btcap.team.membership.membership import TeamEvent
from btcap.transports.log import get_logger

if TYPE_CHECKING:
    from btcap.team.deployment.departed import DepartureView
    from btcap.team.runtime.agent import Agent

__all__ = ["Joining", "departure_rows"]

log = get_logger(__name__)


class Joining:
    """Watches one agent: did a teammate ever answer it, and who refused its key?

    A robot without seeds starts a team of its own, so it is in one from the start.
    """

    def __init__(self, seeds: dict[str, str]) -> None:
        self.seeds = seeds
        self.agent: Agent | None = None
        self.joined = not seeds

    def watch(self, agent: Agent) -> None:
        """Follow ``agent``'s team; a teammate's failure becomes a warning in its log
        (what a robot run from the command line shows by default)."""
        self.agent = agent
        agent.departures.loud = True
        self.joined = self.joined or bool(agent.team.members)
        agent.team.subscribe(self._on_team)
        if not self.joined:  # a robot that waits in silence says why, once (at info)
            wait = min(10.0, max(1.0, 2 * agent.config.failure_timeout_s))
            agent.system.start_task(self._not_yet(wait), name=f"joining {agent.robot}")

    async def _not_yet(self, wait: float) -> None:
        assert self.agent is not None
        await self.agent.clock.sleep(wait)
        if not self.joined:
            log.info("agent.not_joined", robot=self.agent.robot, waited_s=wait, why=self.why_not())

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event is TeamEvent.JOINED:
            self.joined = True

    def refused(self) -> str:
        """What the peers that refused our handshake said ("" if none did)."""
        transport = None if self.agent is None else self.agent.system.transport
        return "" if transport is None else "; ".join(transport.stats.refused_by.values())

    def why_not(self) -> str:
        """Why no teammate answered: who refused us, else the silence of the seeds."""
        return self.refused() or f"no answer from {', '.join(sorted(self.seeds))} yet"

    def silent(self, seeds: Sequence[str], refused: str | None = None) -> str:
        """Why ``seeds`` did not answer, and what to check (``refused``: what
        :meth:`refused` said while the robot was up)."""
        refused = self.refused() if refused is None else refused
        if refused:
            return refused
        where = ", ".join(f"{s} at {self.seeds[s]}" for s in seeds if s in self.seeds)
        up = "is it up" if len(seeds) == 1 else "are they up"
        return f"{up} ({where} in network.seeds), or is --wait too short?"

    def stopping(self, doing: str) -> str:
        """What a signal's line says the command does: ``doing`` once in the team."""
        if self.joined:
            return doing
        return f"stopping, never joined the team: {self.why_not()}"


def departure_rows(
    departures: Sequence[DepartureView], now: float | None = None
) -> list[tuple[str, ...]]:
    """The table ``btcap team status`` prints under the members: robot, what, when (this
    host's local time and how long ago), why."""
    wall = time.time() if now is None else now
    rows: list[tuple[str, ...]] = [("robot", "what", "when", "why")]
    for d in departures:
        at = time.strftime("%H:%M:%S", time.localtime(wall - d.age_s))
        rows.append((d.robot, d.how, f"{at} ({d.age_s:.1f} s ago)", d.why))
    return rows
