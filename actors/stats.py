"""What an actor system counts, so undelivered or refused mail is visible, never silent."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SystemStats"]


@dataclass(slots=True)
class SystemStats:
    """Counters of undelivered mail by reason; ``refused``: local-only mail that came
    from a transport, by message kind (e.g. "Tick")."""

    dead_letters: int = 0
    escalations: int = 0
    dropped: dict[str, int] = field(default_factory=dict)
    failures: dict[str, int] = field(default_factory=dict)
    """Handler failures by ``Actor class: message type: error type`` (bounded by the code,
    not by what peers send)."""
    refused: dict[str, int] = field(default_factory=dict)
