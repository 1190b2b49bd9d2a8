"""Moved to :mod:`btcap.team.spawn` and :mod:`btcap.team.agentspec`; this path re-exports
them for one release."""

import warnings

from btcap.team.agentspec import AgentSpec
from btcap.team.spawn import AgentProcess, spawn_agent, spawn_agents

__all__ = ["AgentProcess", "AgentSpec", "spawn_agent", "spawn_agents"]

warnings.warn(
    "btcap.launch moved to btcap.team.spawn and btcap.team.agentspec; import it from there",
    DeprecationWarning,
    stacklevel=2,
)
