"""Consensus-based allocation (CBAA, Choi, Brunet and How 2009) as pure state: no auctioneer.

Every robot keeps the same three tables and changes them only on explicit input:

- the **open tasks**, each origin's set under a version the origin alone raises (an origin
  speaks for its own tasks only, and at most ``max_tasks`` of them are kept per origin);
- the **claims**: each robot's single current claim (a task and its cost, or none) under a
  stamp the claimant alone raises. A robot speaks only for itself, so the table is a
  last-writer-wins register per robot: merging is commutative, associative and
  idempotent, which is why reordered or repeated messages change nothing;
- the **views** peers reported: which claim stamp and task version of every member they
  had merged when they last spoke (a version vector).

The winner of a task is its best claim by (cost, robot id) among its candidates: the
max-consensus on winning bids of CBAA, computed from the claims instead of relayed lists
(the team's transport reaches every member, so the network's diameter is one).
:meth:`Consensus.select` is CBAA's auction phase: the robot claims the task it does
cheapest among those where it beats the current winner (ties by task id), or nothing.
In the monotone phase (no task closed, nobody lost) the best bid on a task only falls,
so this is the classic rule "re-select only when outbid" and the result is the
sequential greedy assignment; after a task closes or a robot is lost, the same rule
re-allocates what they freed.

A robot has **converged** when every live member's view equals its own vector: all have
merged the same claims and tasks, and each claim in it was made after seeing them, so
no robot would change its claim and no two claim the same task.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Generic, TypeVar

from btcap.team.ids import ExecutionId

__all__ = ["Claim", "Consensus", "Task", "Vector"]

T = TypeVar("T")

#: robot -> (claim stamp, task version) as one robot has merged them.
Vector = dict[str, tuple[int, int]]


@dataclass(frozen=True, slots=True)
class Claim:
    """What ``robot`` says it wins: ``task`` at ``cost`` (lower is better), or nothing."""

    robot: str
    stamp: int
    task: ExecutionId | None = None
    cost: float = math.inf

    def rank(self) -> tuple[float, str]:
        return (self.cost, self.robot)


@dataclass(frozen=True, slots=True)
class Task(Generic[T]):
    """An open task: who may run it, and the origin's description (opaque here)."""

    id: ExecutionId
    candidates: frozenset[str]
    spec: T


@dataclass(slots=True)
class _Offer(Generic[T]):
    version: int
    tasks: dict[ExecutionId, Task[T]] = field(default_factory=dict)


class Consensus(Generic[T]):
    """One robot's side of the consensus; see the module docstring.

    ``dropped`` counts tasks and view entries over the bounds a peer sent; ``refused``
    counts messages that spoke for someone else or made no sense. Both are the shell's to
    log (the core does no I/O). Robots not (or no longer) members are not heard at all.
    """

    def __init__(self, robot: str, *, max_tasks: int = 64, max_members: int = 1024) -> None:
        self.robot = robot
        self.max_tasks = max_tasks
        self.max_members = max_members
        self.members: set[str] = {robot}
        self.claims: dict[str, Claim] = {robot: Claim(robot, 0)}
        self._offers: dict[str, _Offer[T]] = {robot: _Offer(0)}
        self.views: dict[str, Vector] = {}
        self._seq: dict[str, int] = {}  # newest message number heard per peer
        self.dropped = 0
        self.refused = 0

    # -- the team ---------------------------------------------------------------------
    def join(self, robot: str) -> None:
        """A member to hear from (its earlier life, if any, was forgotten when it was lost)."""
        if robot not in self.members and len(self.members) < self.max_members:
            self.members.add(robot)

    def lose(self, robot: str) -> None:
        """A member left or failed: its claim and its tasks go, and what it held is free
        for the next :meth:`select`."""
        if robot == self.robot:
            return
        self.members.discard(robot)
        self.claims.pop(robot, None)
        self._offers.pop(robot, None)
        self.views.pop(robot, None)
        self._seq.pop(robot, None)

    # -- this robot's own tasks -------------------------------------------------------
    def open(self, task: Task[T]) -> None:
        if task.id.origin != self.robot:
            raise ValueError(f"task {task.id}: only its origin {task.id.origin} offers it")
        mine = self._offers[self.robot]
        mine.tasks[task.id] = task
        mine.version += 1

    def close(self, task: ExecutionId) -> None:
        mine = self._offers[self.robot]
        if mine.tasks.pop(task, None) is not None:
            mine.version += 1

    def restrict(self, task: ExecutionId, robot: str) -> None:
        """``robot`` may no longer take this robot's ``task`` (it declined the award)."""
        mine = self._offers[self.robot]
        t = mine.tasks.get(task)
        if t is not None and robot in t.candidates:
            mine.tasks[task] = Task(t.id, t.candidates - {robot}, t.spec)
            mine.version += 1

    @property
    def version(self) -> int:
        return self._offers[self.robot].version

    def own_tasks(self) -> list[Task[T]]:
        return list(self._offers[self.robot].tasks.values())

    # -- what peers say ---------------------------------------------------------------
    def offer(self, sender: str, version: int, tasks: Iterable[Task[T]]) -> bool:
        """``sender``'s open tasks as of ``version``; True if they replaced older ones.
        Tasks of another origin are refused, those over ``max_tasks`` dropped."""
        if sender not in self.members - {self.robot}:
            return False  # a stranger (perhaps not yet heard of): nothing kept
        old = self._offers.get(sender)
        if old is not None and version <= old.version:
            return False  # a repeat or overtaken
        kept: dict[ExecutionId, Task[T]] = {}
        for t in tasks:
            if t.id.origin != sender:
                self.refused += 1
            elif len(kept) >= self.max_tasks:
                self.dropped += 1
            else:
                kept[t.id] = t
        self._offers[sender] = _Offer(version, kept)
        return True

    def hear(
        self, sender: str, seq: int, claim: Claim, view: Mapping[str, tuple[int, int]]
    ) -> bool:
        """A peer's claim and view in its message number ``seq``; True if news. A claim
        for someone else, or with an impossible cost, is refused."""
        if sender not in self.members - {self.robot}:
            return False  # a stranger (perhaps not yet heard of): nothing kept
        if claim.robot != sender:
            self.refused += 1
            return False
        if claim.task is not None and not (math.isfinite(claim.cost) and claim.cost >= 0):
            self.refused += 1
            return False
        if seq <= self._seq.get(sender, 0):
            return False
        self._seq[sender] = seq
        kept: Vector = {}
        for robot, stamps in view.items():
            if robot in self.members:
                kept[robot] = stamps
            else:
                self.dropped += 1
        self.views[sender] = kept
        old = self.claims.get(sender)
        if old is None or claim.stamp > old.stamp:
            self.claims[sender] = claim
        return True

    # -- deciding ---------------------------------------------------------------------
    def tasks(self) -> dict[ExecutionId, Task[T]]:
        """Every open task known, of live origins."""
        return {i: t for o in self._offers.values() for i, t in o.tasks.items()}

    def winners(self, *, without: str | None = None) -> dict[ExecutionId, Claim]:
        """The best claim on each open task (by cost, then robot id), from its candidates."""
        tasks = self.tasks()
        best: dict[ExecutionId, Claim] = {}
        for c in self.claims.values():
            if c.task is None or c.robot == without:
                continue
            t = tasks.get(c.task)
            if t is None or c.robot not in t.candidates:
                continue
            held = best.get(c.task)
            if held is None or c.rank() < held.rank():
                best[c.task] = c
        return best

    def select(self, costs: Mapping[ExecutionId, float]) -> bool:
        """Claim the task this robot does cheapest among those where it beats the current
        winner (``costs``: its own, for the tasks it can take now). True if the claim
        changed, so peers must hear it."""
        others = self.winners(without=self.robot)
        tasks = self.tasks()
        choice: tuple[float, str, ExecutionId] | None = None
        for want, price in costs.items():
            t = tasks.get(want)
            if t is None or self.robot not in t.candidates or not math.isfinite(price):
                continue
            held = others.get(want)
            if held is not None and held.rank() <= (price, self.robot):
                continue  # outbid
            key = (price, str(want), want)
            if choice is None or key[:2] < choice[:2]:
                choice = key
        mine = self.claims[self.robot]
        task: ExecutionId | None = None if choice is None else choice[2]
        cost = math.inf if choice is None else choice[0]
        if (mine.task, mine.cost) == (task, cost) and mine.stamp > 0:
            return False
        self.claims[self.robot] = Claim(self.robot, mine.stamp + 1, task, cost)
        return True

    @property
    def claim(self) -> Claim:
        return self.claims[self.robot]

    def vector(self) -> Vector:
        """What this robot has merged: every member's claim stamp and task version."""
        out: Vector = {}
        for robot in self.members:
            claim = self.claims.get(robot)
            offer = self._offers.get(robot)
            out[robot] = (claim.stamp if claim else 0, offer.version if offer else 0)
        return out

    def converged(self) -> bool:
        """Every member has claimed (or said it claims nothing) after seeing what this
        robot has seen, and reports the same: no claim will change until something new."""
        mine = self.vector()
        if any(stamp == 0 for stamp, _version in mine.values()):
            return False  # someone has not spoken yet
        return all(self.views.get(r) == mine for r in self.members if r != self.robot)

    def waiting_for(self) -> frozenset[str]:
        """Members whose view differs from this robot's (for logs and reasons)."""
        mine = self.vector()
        return frozenset(r for r in self.members if r != self.robot and self.views.get(r) != mine)
