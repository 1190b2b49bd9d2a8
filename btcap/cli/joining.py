"""Whether a robot started from a config file ever joined its team, and if not, why, in
the words the team commands print (on a signal, or when the seeds stay silent).

Imported by a command once it runs (it loads the team layer)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from btcap.team.membership.membership import TeamEvent

if TYPE_CHECKING:
    from btcap.team.runtime.agent import Agent

__all__ = ["Joining"]


class Joining:
    """Watches one agent: did a teammate ever answer it, and who refused its key?

    A robot without seeds starts a team of its own, so it is in one from the start.
    """

    def __init__(self, seeds: dict[str, str]) -> None:
        self.seeds = seeds
        self.agent: Agent | None = None
        self.joined = not seeds

    def watch(self, agent: Agent) -> None:
        self.agent = agent
        self.joined = self.joined or bool(agent.team.members)
        agent.team.subscribe(self._on_team)

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        if event is TeamEvent.JOINED:
            self.joined = True

    def why_not(self) -> str:
        """Why no teammate answered: what the peers that refused us said, else silence."""
        transport = None if self.agent is None else self.agent.system.transport
        refused = [] if transport is None else list(transport.stats.refused_by.values())
        if refused:
            return "; ".join(refused)
        return f"no answer from {', '.join(sorted(self.seeds))} yet"

    def stopping(self, doing: str) -> str:
        """What a signal's line says the command does: ``doing`` once in the team."""
        if self.joined:
            return doing
        return f"stopping, never joined the team: {self.why_not()}"
