"""The team-wide shared store: found objects, their status, and exploration goals.

:class:`MissionState` is plain state (no I/O) owned by the simulation; the
:class:`ObjectStore` actor hands out work from it to mission trees. Each claimant holds at
most one claim; claiming again releases the previous one unless its work was finished,
so work abandoned by a failed robot is offered again and nothing is lost or done twice.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from btcap.actors import Actor, handler
from btcap.sim.world.distance import Cell
from btcap.sim.world.grid import GridMap
from btcap.sim.world.messages import Claim, ClaimReply, ListWork, WorkList

__all__ = ["Goal", "MissionState", "ObjectStore", "SimObject"]


@dataclass(slots=True)
class SimObject:
    id: int
    cell: Cell
    contaminated: bool  # ground truth, known to the simulation only
    found: bool = False
    identified: bool | None = None  # what identification said
    decontaminated: bool = False
    carried_by: str | None = None
    claimed_by: str | None = None
    seen: int = -1  # the order in which objects were found (and then identified)

    @property
    def finished(self) -> bool:
        return self.decontaminated or self.identified is False

    @property
    def available(self) -> bool:
        return (
            self.found and not self.finished and self.claimed_by is None and self.carried_by is None
        )


@dataclass(slots=True)
class Goal:
    id: int
    cell: Cell
    done: bool = False
    claimed_by: str | None = None


@dataclass
class MissionState:
    """Ground truth and progress of the find-and-decontaminate mission."""

    grid: GridMap
    objects: list[SimObject]
    goals: dict[int, Goal] = field(default_factory=dict)
    covered: NDArray[np.bool_] = field(init=False)
    claims: dict[str, tuple[Literal["goal", "object"], int]] = field(default_factory=dict)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    _next_goal: int = 0
    _next_seen: int = 0
    #: Grows whenever an object changes what a picture of it shows (found, identified,
    #: picked up, dropped, decontaminated): a watcher (the monitor's world feed, at every
    #: simulation step) needs no walk over the objects to see that none did.
    changes: int = field(default=0, init=False)
    #: Each cell's rank among frontier cells that may become goals, drawn once: which
    #: cells become goals depends on the frontier, not on how many explorations drew before.
    _rank: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        self.covered = np.zeros(self.grid.shape, dtype=bool)
        self._rank = self.rng.random(self.grid.shape)
        self.add_goal(self.grid.start)

    @classmethod
    def scatter(
        cls, grid: GridMap, n_objects: int, contaminated_share: float, rng: np.random.Generator
    ) -> MissionState:
        cells = grid.random_free_cells(n_objects, rng)
        dirty = rng.random(n_objects) < contaminated_share
        objs = [
            SimObject(i, (int(r), int(c)), bool(d))
            for i, ((r, c), d) in enumerate(zip(cells, dirty, strict=True))
        ]
        return cls(grid, objs, rng=rng)

    # -- goals ------------------------------------------------------------------------
    def add_goal(self, cell: Cell) -> Goal:
        g = Goal(self._next_goal, cell)
        self.goals[g.id] = g
        self._next_goal += 1
        return g

    def pending_goals(self) -> list[Goal]:
        return [g for g in self.goals.values() if not g.done]

    def frontier(self) -> NDArray[np.bool_]:
        """Reachable cells not yet covered that border covered ones."""
        c = self.covered
        near = np.zeros_like(c)
        near[1:, :] |= c[:-1, :]
        near[:-1, :] |= c[1:, :]
        near[:, 1:] |= c[:, :-1]
        near[:, :-1] |= c[:, 1:]
        return near & ~c & self.grid.reachable

    @property
    def coverage(self) -> float:
        reach = self.grid.reachable
        return float((self.covered & reach).sum() / max(1, reach.sum()))

    @property
    def exploration_complete(self) -> bool:
        return not self.pending_goals() and not self.frontier().any()

    def explore(self, cell: Cell, radius_m: float) -> int:
        """Cover a disc around ``cell``: reveal objects in it and add goals on its frontier.

        Returns how many objects were newly found.
        """
        g = self.grid
        r = radius_m / g.cell_size_m
        rows, cols = np.ogrid[: g.height, : g.width]
        disc = (rows - cell[0]) ** 2 + (cols - cell[1]) ** 2 <= r * r
        self.covered |= disc & g.reachable
        found = 0
        for o in self.objects:
            if not o.found and disc[o.cell]:
                o.found = True
                o.seen = self._next_seen
                self._next_seen += 1
                found += 1
        self.changes += found
        for goal in self.goals.values():
            if not goal.done and goal.claimed_by is None and self.covered[goal.cell]:
                goal.done = True
        self._new_goals(max(r, 2.0))
        return found

    def _new_goals(self, spacing: float) -> None:
        cand = np.argwhere(self.frontier())
        if len(cand) == 0:
            return
        # A covered goal is done once its claimant lets go: it stands for no frontier.
        taken = [g.cell for g in self.pending_goals() if not self.covered[g.cell]]
        cand = cand[np.argsort(self._rank[cand[:, 0], cand[:, 1]], kind="stable")]
        keep = np.ones(len(cand), dtype=bool)
        for t in taken:
            keep &= ((cand - np.asarray(t)) ** 2).sum(axis=1) > spacing * spacing
        while keep.any():
            i = int(np.flatnonzero(keep)[0])
            cell = (int(cand[i, 0]), int(cand[i, 1]))
            self.add_goal(cell)
            keep &= ((cand - cand[i]) ** 2).sum(axis=1) > spacing * spacing

    def goal_done(self, goal_id: int) -> None:
        g = self.goals.get(goal_id)
        if g is not None:
            g.done = True
            if g.claimed_by is not None:
                self.claims.pop(g.claimed_by, None)
                g.claimed_by = None

    # -- claims -----------------------------------------------------------------------
    def release(self, claimant: str) -> None:
        held = self.claims.pop(claimant, None)
        if held is None:
            return
        kind, ident = held
        if kind == "goal":
            g = self.goals.get(ident)
            if g is not None and g.claimed_by == claimant:
                g.claimed_by = None
                if self.covered[g.cell]:
                    g.done = True
        else:
            o = self.objects[ident]
            if o.claimed_by == claimant:
                o.claimed_by = None

    def claim(self, claimant: str, kind: str) -> ClaimReply:
        self.release(claimant)
        if kind == "goal":
            for g in self.goals.values():
                if not g.done and g.claimed_by is None:
                    g.claimed_by = claimant
                    self.claims[claimant] = ("goal", g.id)
                    return ClaimReply("ok", g.id, g.cell)
            busy = any(g.claimed_by is not None for g in self.goals.values() if not g.done)
            return ClaimReply("wait" if busy or self.frontier().any() else "done")
        if kind == "object":
            for o in self.objects:
                if o.available:
                    o.claimed_by = claimant
                    self.claims[claimant] = ("object", o.id)
                    return ClaimReply("ok", o.id, o.cell, o.identified is not None)
            pending = any(o.found and not o.finished for o in self.objects)
            if pending or not self.exploration_complete:
                return ClaimReply("wait")
            return ClaimReply("done")
        raise ValueError(f"claim kind {kind!r}: expected 'goal' or 'object'")

    def work_list(self, kind: str) -> WorkList:
        """The work of ``kind`` waiting now (a pool mission's lanes take it, without
        claims): goals not yet explored, found objects not yet identified, objects found
        contaminated and not yet carried away, or (``object``) every found object with work
        left, flagged 1 once known contaminated; ``complete`` once no more can come."""
        explored = self.exploration_complete
        items: list[tuple[int, ...]]
        if kind == "goal":
            items = [(g.id, *g.cell) for g in self.goals.values() if not g.done]
            return WorkList(items, explored)
        # the oldest news first: objects in the order they were found, then identified
        found = sorted(
            (o for o in self.objects if o.found and not o.finished), key=lambda o: o.seen
        )
        if kind == "identify":
            items = [(o.id, *o.cell) for o in found if o.identified is None and not o.carried_by]
            return WorkList(items, explored)
        if kind == "carry":
            items = [(o.id, *o.cell) for o in found if o.identified]
            return WorkList(items, explored and all(o.identified is not None for o in found))
        if kind == "object":  # all its work left: identify (flag 0) or carry (flag 1)
            items = [
                (o.id, *o.cell, int(bool(o.identified)))
                for o in found
                if o.identified or not o.carried_by
            ]
            return WorkList(items, explored)
        raise ValueError(f"work kind {kind!r}: expected 'goal', 'identify', 'carry' or 'object'")

    # -- objects ----------------------------------------------------------------------
    def identify(self, obj: int) -> bool:
        o = self.objects[obj]
        o.identified = o.contaminated
        self.changes += 1
        o.seen = self._next_seen  # the carries in the order the objects were identified
        self._next_seen += 1
        return o.contaminated

    def pick_up(self, obj: int, robot: str) -> None:
        self.objects[obj].carried_by = robot
        self.changes += 1

    def drop(self, obj: int, cell: Cell) -> None:
        """The carrier failed: the object stays where it fell, still to be decontaminated."""
        o = self.objects[obj]
        o.carried_by = None
        o.cell = cell
        self.changes += 1

    def decontaminated(self, obj: int) -> None:
        o = self.objects[obj]
        o.carried_by = None
        o.decontaminated = True
        o.cell = self.grid.decon_area
        self.changes += 1

    @property
    def mission_complete(self) -> bool:
        return self.exploration_complete and all(o.finished for o in self.objects if o.found)

    def summary(self) -> dict[str, int | float]:
        found = [o for o in self.objects if o.found]
        return {
            "objects": len(self.objects),
            "found": len(found),
            "identified": sum(o.identified is not None for o in found),
            "contaminated": sum(bool(o.identified) for o in found),
            "decontaminated": sum(o.decontaminated for o in found),
            "goals": len(self.goals),
            "coverage": round(self.coverage, 4),
        }


class ObjectStore(Actor):
    """Hands out exploration goals and objects to the mission's work loops."""

    PATH = "store"

    def __init__(self, state: MissionState) -> None:
        super().__init__()
        self.state = state

    @handler
    def on_claim(self, msg: Claim) -> ClaimReply:
        if msg.kind not in ("goal", "object"):
            return ClaimReply("done")
        return self.state.claim(msg.claimant, msg.kind)

    @handler
    def on_list_work(self, msg: ListWork) -> WorkList:
        if msg.kind not in ("goal", "identify", "carry", "object"):
            return WorkList([], True)
        return self.state.work_list(msg.kind)
