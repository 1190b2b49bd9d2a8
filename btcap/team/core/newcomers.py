"""Members that have not yet answered us, and forgetting them once silent (sans-IO).

Anybody who can send us a heartbeat joins (keyless, anybody at all): a flood of made-up
members, each beating a while and then silent, would otherwise stay until its turn in
the probe round came, one member a period, minutes for a thousand. So a newcomer is
probed at once with a nonce only a robot that receives our messages can echo, and again
every period while it has not answered (at most :data:`RETRIES_PER_PERIOD` of them a
period, the least recently asked first). Until it answers, nothing it passes on counts,
nobody is told of it and it helps no probe; never confirmed and silent for
:meth:`~btcap.team.core.swim.SwimParams.forget_s`, it is forgotten (declared failed
without a suspicion: nobody else needs to agree about a member only we held).
"""

from __future__ import annotations

import random
from collections.abc import Mapping
from dataclasses import dataclass

from btcap.team.core.members import Member

__all__ = ["RETRIES_PER_PERIOD", "Newcomers"]

RETRIES_PER_PERIOD = 16
"""Confirmation probes repeated per period, at most: a thousand made-up members cost a
bounded share of each period, and a real newcomer among them is asked within
``1000 / 16`` periods however many arrived together."""


@dataclass(slots=True)
class _Waiting:
    nonce: int
    asked: float  #: when we last probed it


class Newcomers:
    """The members not confirmed yet, in the order they were last asked."""

    __slots__ = ("_rng", "_waiting")

    def __init__(self, rng: random.Random) -> None:
        self._rng = rng
        self._waiting: dict[str, _Waiting] = {}

    def __contains__(self, robot: object) -> bool:
        return robot in self._waiting

    def __len__(self) -> int:
        return len(self._waiting)

    def joined(self, robot: str, now: float) -> int:
        """``robot`` just joined: the nonce to probe it with now."""
        nonce = self._rng.randrange(1 << 40, 1 << 62)  # never a probe number of ours
        self._waiting.pop(robot, None)
        self._waiting[robot] = _Waiting(nonce, now)
        return nonce

    def answered(self, robot: str, ack: int) -> bool:
        """Whether ``ack`` from ``robot`` answers our nonce (then it is confirmed)."""
        w = self._waiting.get(robot)
        if w is None or w.nonce != ack:
            return False
        del self._waiting[robot]
        return True

    def confirm(self, robot: str) -> bool:
        """``robot`` answered one of our probes (directly or through a helper)."""
        return self._waiting.pop(robot, None) is not None

    def due(
        self, members: Mapping[str, Member], now: float, every_s: float
    ) -> list[tuple[str, int]]:
        """Newcomers to probe again now (asked ``every_s`` ago or longer), with their
        nonce, at most :data:`RETRIES_PER_PERIOD`; each then counts as asked now."""
        out: list[tuple[str, int]] = []
        for robot, w in self._waiting.items():
            if len(out) >= RETRIES_PER_PERIOD or now - w.asked < every_s:
                break  # in the order asked: the rest were asked later
            if robot in members:
                out.append((robot, w.nonce))
        for robot, _ in out:
            w = self._waiting.pop(robot)
            w.asked = now
            self._waiting[robot] = w
        return out

    def silent(self, members: Mapping[str, Member], now: float, after_s: float) -> list[str]:
        """Newcomers not heard from directly for ``after_s`` (forgotten here, returned),
        and any that stopped being members meanwhile (forgotten silently)."""
        gone, left = [], []
        for robot in self._waiting:
            m = members.get(robot)
            if m is None:
                left.append(robot)
            elif now - m.last_direct >= after_s:
                gone.append(robot)
        for robot in gone + left:
            del self._waiting[robot]
        return gone
