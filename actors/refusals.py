"""Mail a recipient refused: counted per sender and message kind, logged once per pair.

A refused message is an attempt to do what the sender has no right to, so its first
occurrence from each sender deserves a line of its own; repeats only a reminder at
every power of two from 1024 on. The table is bounded: a keyless peer can name itself
anything, and past :data:`MAX_PAIRS` pairs the newcomers share one line per kind.
"""

from __future__ import annotations

__all__ = ["MAX_PAIRS", "OTHERS", "Refusals"]

#: Distinct (sender, kind) pairs remembered; later senders are counted as :data:`OTHERS`.
MAX_PAIRS = 1024
#: The sender newcomers are counted under once the table is full (no system id is "*").
OTHERS = "*"


class Refusals:
    """How often each sender had each kind of message refused."""

    __slots__ = ("_counts", "limit")

    def __init__(self, limit: int = MAX_PAIRS) -> None:
        self.limit = limit
        self._counts: dict[tuple[str, str], int] = {}

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
