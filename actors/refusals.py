"""Mail a recipient refused: counted by kind, logged once per sender and kind.

A ``local_only`` message (see :func:`~btcap.actors.handlers.handler`) that came from a
transport is an attempt to do what the sender has no right to, so its first occurrence
from each sender deserves a line of its own; repeats only a reminder at every power of
two from 1024 on. The table is bounded: a keyless peer can name itself anything, and
past :data:`MAX_PAIRS` pairs the newcomers share one count per kind.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from btcap.actors.errors import Refused
from btcap.transports.codec import Envelope, Kind

__all__ = ["MAX_PAIRS", "OTHERS", "Refusals"]

#: Distinct (sender, kind) pairs remembered; later senders are counted as :data:`OTHERS`.
MAX_PAIRS = 1024
#: The sender newcomers are counted under once the table is full (no system id is "*").
OTHERS = "*"


class Refusals:
    """How often each sender had each kind of message refused by one actor system."""

    __slots__ = ("_counts", "_log", "limit", "system_id")

    def __init__(self, system_id: str, log: Any, limit: int = MAX_PAIRS) -> None:
        self.system_id = system_id
        self.limit = limit
        self._log = log
        self._counts: dict[tuple[str, str], int] = {}

    def refuse(
        self,
        env: Envelope,
        by_kind: dict[str, int],
        reply: Callable[[Envelope, Any, BaseException | None], None],
    ) -> None:
        """Count ``env`` (also in ``by_kind``, the system's stats), log it if it is the
        first of its sender and kind, and ``reply`` to an ask with :class:`Refused`."""
        name = type(env.msg).__qualname__
        by_kind[name] = by_kind.get(name, 0) + 1
        sender = env.sender.system
        counted_as, n = self.count(sender, name)
        to = f"{self.system_id}/{env.recipient.path}"
        if self.worth_logging(n):
            more = {} if counted_as == sender else {"counted_as": counted_as}
            self._log.warning("actors.refused", sender=sender, message=name, to=to, count=n, **more)
        if env.kind is Kind.ASK:
            why = f"{name} to {to} is taken only from inside {self.system_id}, not from {sender}"
            reply(env, None, Refused(why))

    def count(self, sender: str, kind: str) -> tuple[str, int]:
        """Count one refusal; the sender it was counted under and the pair's count."""
        counts = self._counts
        key = (sender, kind)
        if key not in counts and len(counts) >= self.limit:
            key = (OTHERS, kind)
        n = counts[key] = counts.get(key, 0) + 1
        return key[0], n

    @staticmethod
    def worth_logging(n: int) -> bool:
        """The first refusal of a pair, then every power of two from 1024 on."""
        return n == 1 or (n >= 1024 and n & (n - 1) == 0)

    def __len__(self) -> int:
        return len(self._counts)
