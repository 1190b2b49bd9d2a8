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


class TeamView:
    """Robots with their trees and membership, executions, auctions and marks."""

    def __init__(self) -> None:
        self.t = 0.0
        self.robots: dict[str, dict[str, Any]] = {}
        self.runs: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self.auctions: OrderedDict[str, dict[str, Any]] = OrderedDict()
        self.marks: list[dict[str, Any]] = []

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
            }
            while len(self.auctions) > MAX_AUCTIONS:
                self.auctions.popitem(last=False)
        elif key in self.auctions:
            self.auctions[key].update(
                closed=ev["t"],
                bids=ev["bids"],
                declined=ev["declined"],
                reasons=ev["reasons"],
                winner=ev["winner"],
            )

    def snapshot(self) -> dict[str, Any]:
        """The picture as JSON-ready data (what ``/api/state`` serves)."""
        return {
            "t": self.t,
            "robots": self.robots,
            "runs": list(self.runs.values()),
            "auctions": list(self.auctions.values()),
            "marks": self.marks,
        }
