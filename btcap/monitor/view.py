"""The team picture a monitor shows, built only from its events.

Live monitors and replays feed the same events to a :class:`TeamView`, so a recording
replayed to its end shows exactly what the live page showed. The browser applies the
same events to the same JSON shape (``static/app.js``, ``apply``): keep the two in step.

Events are JSON objects with a clock time ``t`` and a kind ``k``:

- ``robot``: ``robot`` is part of the picture.
- ``tree``: the structure of one tree of ``robot``: ``nodes``, a list of
  ``{"id": path, "name", "type", "parent": path | None, "cap": bool, "state"}``.
- ``states``: ``{"robot", "tree", "states": {path: state}}``, the latest state of each
  node that changed (several changes between two batches count once).
- ``team``: ``robot`` joined, left or failed (``change``).
- ``run``: an execution started (``phase`` ``start``: ``robot`` runs ``capability`` of
  ``origin``'s node ``node``) or ended (``phase`` ``end``, ``result``, ``why``).
- ``auction``: opened (``phase`` ``open``: ``capability``, ``node``, ``candidates``,
  ``why``) or closed (``phase`` ``close``: ``bids`` ``[[robot, cost], ...]`` cheapest
  first, ``declined`` (would not bid) and ``reasons`` (why a robot was passed over:
  no answer, a bid not below the reserve, the award declined) per robot, ``winner``).
  An auction that closes as the last one for the same node did is folded into that one's
  row, which then stands for ``count`` auctions held from ``first`` to ``opened`` (the
  latest) and shows the latest one's bids: a task retried for minutes is one row, not a
  table of copies. Alike means the same capability, auctioneer, why and winner, and then,
  for one that somebody won, the same bids, declines and reasons; for one nobody took (a
  retry, a re-evaluation that kept the work where it was) the same robots bidding,
  declining and passed over, whatever they asked: a busy robot's cost changes as it
  drives, and every retry would otherwise be a row of its own.
- ``finished``: the run is over: ``result`` (``succeeded``, ``failed`` or ``stopped``)
  and ``summary``, one line for a person ("mission succeeded after 1337 s"). The picture
  keeps the last one (a page shows the final state, not a lost connection).
- ``map`` and ``world``: a simulation's map and what changed in it (robots' poses and
  tasks, objects), for Foxglove (:mod:`btcap.monitor.scene`); the picture ignores them.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

__all__ = ["MAX_AUCTIONS", "MAX_MARKS", "MAX_RUNS", "Event", "TeamView"]

Event = dict[str, Any]

#: What the picture keeps of the past (a recording keeps everything).
MAX_RUNS = 2000
MAX_AUCTIONS = 200
MAX_MARKS = 500

#: What two auctions of one node must share to be shown as one row.
_SAME = ("capability", "auctioneer", "why", "winner")
#: What they must share as well when somebody won: exactly the same auction.
_WON = ("bids", "declined", "reasons")


class TeamView:
    """Robots with their trees and membership, executions, auctions and marks."""

    def __init__(self) -> None:
        self.t = 0.0
        self.robots: dict[str, dict[str, Any]] = {}
        self.runs: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self.auctions: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self.marks: list[dict[str, Any]] = []
        self.finished: dict[str, Any] | None = None

    def robot(self, name: str) -> dict[str, Any]:
        r = self.robots.get(name)
        if r is None:
            r = self.robots[name] = {"status": "seen", "trees": {}}
        return r

    def apply(self, ev: Event) -> None:
        """Fold one event into the picture (unknown kinds are ignored, for old viewers)."""
        self.t = max(self.t, float(ev["t"]))
        kind = ev["k"]
        if kind == "robot":
            self.robot(ev["robot"])
        elif kind == "tree":
            nodes = [dict(n) for n in ev["nodes"]]
            self.robot(ev["robot"])["trees"][ev["tree"]] = {"nodes": nodes}
        elif kind == "states":
            tree = self.robot(ev["robot"])["trees"].get(ev["tree"])
            if tree is not None:
                states = ev["states"]
                for n in tree["nodes"]:
                    if n["id"] in states:
                        n["state"] = states[n["id"]]
        elif kind == "team":
            self.robot(ev["robot"])["status"] = ev["change"]
            self.marks.append({"t": ev["t"], "robot": ev["robot"], "change": ev["change"]})
            del self.marks[:-MAX_MARKS]
        elif kind == "run":
            self._run(ev)
        elif kind == "auction":
            self._auction(ev)
        elif kind == "finished":
            self.finished = {"t": ev["t"], "result": ev["result"], "summary": ev["summary"]}

    def _run(self, ev: Event) -> None:
        key = ev["execution"]
        if ev["phase"] == "start":
            self.robot(ev["robot"])
            self.runs[key] = {
                "execution": key,
                "robot": ev["robot"],
                "origin": ev["origin"],
                "node": ev["node"],
                "capability": ev["capability"],
                "start": ev["t"],
                "end": None,
                "result": None,
                "why": None,
            }
            while len(self.runs) > MAX_RUNS:
                self.runs.popitem(last=False)
        elif key in self.runs:
            self.runs[key].update(end=ev["t"], result=ev["result"], why=ev.get("why"))

    def _auction(self, ev: Event) -> None:
        key = ev["id"]
        if ev["phase"] == "open":
            self.auctions[key] = {
                "id": key,
                "auctioneer": ev["auctioneer"],
                "capability": ev["capability"],
                "node": ev["node"],
                "execution": ev["execution"],
                "candidates": ev["candidates"],
                "why": ev["why"],
                "opened": ev["t"],
                "closed": None,
                "bids": [],
                "declined": {},
                "reasons": {},
                "winner": None,
                "count": 1,
                "first": ev["t"],
            }
            while len(self.auctions) > MAX_AUCTIONS:
                self.auctions.popitem(last=False)
        elif key in self.auctions:
            row = self.auctions[key]
            row.update(
                closed=ev["t"],
                bids=ev["bids"],
                declined=ev["declined"],
                reasons=ev["reasons"],
                winner=ev["winner"],
            )
            self._fold(row)

    def _fold(self, row: dict[str, Any]) -> None:
        """Fold a closed auction into the row of the last one for its node, if it ended
        the same way (app.js, ``fold``, does the same)."""
        last, before = None, False
        for other in reversed(self.auctions.values()):  # at most MAX_AUCTIONS rows
            if other is row:
                before = True
            elif before and other["node"] == row["node"]:
                last = other
                break
        if last is None or last["closed"] is None or not _alike(last, row):
            return
        row.update(count=last["count"] + 1, first=last["first"])
        del self.auctions[last["id"]]

    def snapshot(self) -> dict[str, Any]:
        """The picture as JSON-ready data (what ``/api/state`` serves)."""
        return {
            "t": self.t,
            "robots": self.robots,
            "runs": list(self.runs.values()),
            "auctions": list(self.auctions.values()),
            "marks": self.marks,
            "finished": self.finished,
        }


def _alike(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Two closed auctions of one node that ended the same way (see the module's doc)."""
    if any(a[f] != b[f] for f in _SAME):
        return False
    if a["winner"] is not None:
        return all(a[f] == b[f] for f in _WON)
    return _who(a) == _who(b)


def _who(row: dict[str, Any]) -> tuple[list[str], list[str], list[str]]:
    """Who bid, who declined and who was passed over, without what they asked or why."""
    return sorted(r for r, _ in row["bids"]), sorted(row["declined"]), sorted(row["reasons"])
