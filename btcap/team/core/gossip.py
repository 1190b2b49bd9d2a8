"""Gossip that scales: whom to probe next, what news to pass on, whom to ask about.

Freshness cannot reach every robot every period with bounded messages; changes can.
So a robot probes one teammate per period (:class:`ProbeOrder`, SWIM's shuffled round
robin) and each message carries a bounded number of news items (:class:`Rumours`: joins,
suspicions, refutations), each passed on ``lambda·log(team)`` times: a change reaches the whole
team in O(log team) periods while messages and bytes per robot and period stay flat.
"""

from __future__ import annotations

import random
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from btcap.team.messages import Heard

__all__ = ["Introductions", "ProbeOrder", "Rumours", "Turns"]


class Turns:
    """Round-robin over a changing set of names, in an order shuffled each round."""

    def __init__(self, rng: random.Random) -> None:
        self._rng = rng
        self._queue: list[str] = []

    def take(self, names: Iterable[str], n: int) -> list[str]:
        """The next ``n`` of ``names`` (all of them when there are at most ``n``)."""
        pool = set(names)
        if len(pool) <= n:
            self._queue.clear()
            return sorted(pool)
        out: list[str] = []
        while len(out) < n:
            if not self._queue:
                self._queue = sorted(pool - set(out))
                self._rng.shuffle(self._queue)
            name = self._queue.pop()
            if name in pool and name not in out:
                out.append(name)
        return out


class Introductions:
    """Who is worth asking about a robot that teammates mention but we cannot reach.

    At most one request per robot per ``interval_s``; at most ``limit`` robots remembered
    (a teammate listing invented robots costs a bounded table, oldest forgotten first).
    """

    def __init__(self, interval_s: float, limit: int = 1024) -> None:
        self.interval_s = interval_s
        self.limit = limit
        self._asked: dict[str, float] = {}

    def due(self, robots: Sequence[str], now: float) -> list[str]:
        """The robots of ``robots`` to ask about now (each then counts as asked)."""
        out = []
        for robot in robots:
            last = self._asked.get(robot)
            if last is not None and now - last < self.interval_s:
                continue
            self._asked.pop(robot, None)
            self._asked[robot] = now
            out.append(robot)
        while len(self._asked) > self.limit:
            del self._asked[next(iter(self._asked))]
        return out

    def __len__(self) -> int:
        return len(self._asked)


class ProbeOrder:
    """Whom to probe next: every member once per round, in an order shuffled each round
    (SWIM's round robin: a member is probed by each teammate within two rounds, and the
    cost is O(1) per probe however large the team)."""

    def __init__(self, rng: random.Random) -> None:
        self._rng = rng
        self._queue: list[str] = []

    def next(self, members: Mapping[str, object]) -> str | None:
        """The next member to probe (None: nobody to probe)."""
        while self._queue:
            name = self._queue.pop()
            if name in members:
                return name
        if not members:
            return None
        self._queue = sorted(members)
        self._rng.shuffle(self._queue)
        return self._queue.pop()


@dataclass(slots=True)
class _Item:
    news: Heard
    sent: int = 0


class Rumours:
    """News to pass on, one item per robot (a newer one replaces the older), each sent
    at most ``times`` times, the least-sent first; at most ``limit`` held (a peer
    inventing robots costs a bounded table, the most-sent dropped first)."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self._news: dict[str, _Item] = {}

    def add(self, news: Heard) -> None:
        self._news.pop(news.robot, None)
        self._news[news.robot] = _Item(news)
        if len(self._news) > self.limit:
            worst = max(self._news, key=lambda r: self._news[r].sent)
            del self._news[worst]

    def drop(self, robot: str) -> None:
        self._news.pop(robot, None)

    def about(self, robot: str) -> Heard | None:
        item = self._news.get(robot)
        return None if item is None else item.news

    def take(self, n: int, times: int, first: str | None = None) -> list[Heard]:
        """Up to ``n`` items to send now (news of ``first`` first, if any); each counts
        as sent once more and is forgotten after ``times`` sends."""
        news = self._news
        if not news or n <= 0:
            return []
        order = sorted(news, key=lambda r: (r != first, news[r].sent))[:n]
        out: list[Heard] = []
        for robot in order:
            item = news[robot]
            out.append(item.news)
            item.sent += 1
            if item.sent >= times:
                del news[robot]
        return out

    def __len__(self) -> int:
        return len(self._news)
