"""ParallelForEach: a subtree for each item of a list that may grow while it runs.

A mission often finds its work as it goes (objects found while exploring): a fixed
Parallel of loops either holds an item for the whole of its pipeline or waits for the
slowest loop. :class:`ParallelForEach` instead runs one *lane* per item, at most
``max_concurrency`` at once, starting a lane as soon as one is free and an item is
waiting, and taking new items from its ``items`` input on every tick.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any, ClassVar

from btcap.bt.node import Node
from btcap.bt.ports import Port, check_port
from btcap.bt.state import State, TreeError
from btcap.bt.utility import Utility, parallel_utility

__all__ = ["ParallelForEach"]

_RUNNING = State.RUNNING
_SUCCEEDED = State.SUCCEEDED
_FAILED = State.FAILED
_ERROR = State.ERROR
_IDLE = State.IDLE
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)


class ParallelForEach(Node):
    """Runs a lane (child) for each item of ``items``, at most ``max_concurrency`` at once.

    - Its children are the lanes, alike (built by a function, or each a ``Subtree`` of
      the same tree in a file); each has an input named by option ``item_port`` (default
      ``item``), which gets the lane's item, checked against that input's type, before
      every tick of the lane. ``max_concurrency`` (default: every child) lanes run at once.
    - ``items`` is read on every tick and may grow (or lose items) while the node runs;
      items are told apart by value (hashable), or with option ``key`` by their element
      ``key`` (a tuple's index or a mapping's key): an item whose key is running gets its
      latest value before every tick of its lane (work whose details changed). A new item
      starts in the first free lane, in the list's order; an item runs at most once at a
      time, and an item whose lane succeeded does not run again until the node starts
      over. An item that leaves the list while its lane runs goes on running.
    - A lane that fails (or errs) ends that item: with ``retry_failed`` the item runs again
      while it is still listed (the list's source decides when it is no longer worth it),
      otherwise it is counted in ``failed`` and not run again. ``retry_after_s`` holds it
      back that many clock seconds first, so it runs again from the list's details read
      after the failure (an object dropped where its carrier failed), not from a reading
      taken before it.
    - The node succeeds once ``complete`` is true (the list will not grow any more; wire
      it from the list's source, default true) and no listed item waits or runs; then it
      fails instead if any item failed without a retry. Until then it is RUNNING.
    - A lane is ticked in the tick its item starts; a finished lane is reset before its
      next item, so every item starts from a fresh lane; which waiting item a free lane
      takes is :meth:`order`'s (the list's order unless a subclass says otherwise).
      Untick unticks the running lanes (they keep their progress, as a Parallel's
      children do); reset forgets every item.

    Outputs ``succeeded`` and ``failed`` count the items so far; ``running`` is how many
    lanes run now.
    """

    __slots__ = ("_finished", "_lanes", "_lost", "_restart", "_retry_at", "_values")
    MIN_CHILDREN: ClassVar[int] = 1
    MAX_CHILDREN: ClassVar[int | None] = None
    INPUTS: ClassVar[Any] = {
        "items": Port(list[Any], description="the items, read every tick; it may grow"),
        "complete": Port(bool, True, "true once the list will not grow any more"),
    }
    OUTPUTS: ClassVar[Any] = {"succeeded": int, "failed": int, "running": int}
    OPTIONS: ClassVar[Any] = {
        "max_concurrency": Port(int, 0, "lanes running at once; 0: every child"),
        "item_port": Port(str, "item", "the input of each lane that gets its item"),
        "retry_failed": Port(bool, False, "run an item again after its lane failed"),
        "key": Port(int | str | None, None, "tell items apart by this element of each"),
        "retry_after_s": Port(float, 0.0, "clock seconds a failed item waits to run again"),
    }

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._lanes: list[Hashable | None] = []  # the key of each lane's item, by child
        self._values: list[Any] = []  # and the item's latest value
        self._finished: set[Hashable] = set()
        self._lost: set[Hashable] = set()
        self._restart = False
        self._retry_at: dict[Hashable, float] = {}  # failed items waiting to run again

    def width(self) -> int:
        """How many lanes may run at once; TreeError if the option cannot be met."""
        n, most = len(self.children), self.options["max_concurrency"]
        if most < 0 or most > n:
            raise TreeError(
                f"node {self.path!r} (ParallelForEach): max_concurrency {most} with {n} "
                f"children; expected 0 (every child) to {n}"
            )
        return most or n

    def check_children(self) -> None:
        self.width()
        key = self.options["item_port"]
        for c in self.children:
            if key not in c.input_ports:
                raise TreeError(
                    f"node {self.path!r} (ParallelForEach): lane {c.name!r} has no input "
                    f"{key!r} for its item (inputs: {', '.join(c.input_ports) or 'none'})"
                )

    def feeds(self) -> list[tuple[Node, str]]:
        """The lanes' item inputs: set by this node, so they need no wire or value."""
        key = self.options["item_port"]
        return [(c, key) for c in self.children if key in c.input_ports]

    def on_setup(self) -> None:
        self.check_children()
        self._lanes = [None] * len(self.children)
        self._values = [None] * len(self.children)

    def _key(self, item: Any) -> Hashable:
        key = self.options["key"]
        try:
            k = item if key is None else item[key]
            hash(k)
        except (TypeError, KeyError, IndexError):
            what = "is not hashable" if key is None else f"has no hashable element {key!r}"
            raise TreeError(f"node {self.path!r} (ParallelForEach): item {item!r} {what}") from None
        return k  # type: ignore[no-any-return]

    def _run(self, i: int, item: Any) -> State:
        lane = self.children[i]
        key = self.options["item_port"]
        lane.inputs[key] = check_port(item, lane.input_ports[key], f"{lane.path}.{key}")
        return lane.tick()

    def _ended(self, i: int, s: State) -> bool:
        """Book lane ``i``'s state ``s``; True if its item is done with (for now)."""
        k = self._lanes[i]
        if s is _SUCCEEDED:
            self._finished.add(k)
        elif s is _FAILED or s is _ERROR:
            if not self.options["retry_failed"]:
                self._lost.add(k)
            elif self.options["retry_after_s"] > 0:
                self._retry_at[k] = self.clock.now() + self.options["retry_after_s"]
        else:
            return False
        self._lanes[i] = self._values[i] = None
        return True

    def on_tick(self) -> State:
        if self._restart:  # ticked again after its result: start over
            self._forget()
        n = len(self.children)
        if len(self._lanes) != n:
            self._lanes.extend([None] * (n - len(self._lanes)))
            self._values.extend([None] * (n - len(self._values)))
        if self._retry_at:
            now = self.clock.now()
            self._retry_at = {k: t for k, t in self._retry_at.items() if t > now}
        items = self.inputs["items"] or []
        latest = {self._key(item): item for item in items}
        running: set[Hashable] = set()
        for i, k in enumerate(self._lanes):  # the lanes under way
            if k is None:
                continue
            value = self._values[i] = latest.get(k, self._values[i])
            if not self._ended(i, self._run(i, value)):
                running.add(k)
        width = self.width()
        free = [i for i, k in enumerate(self._lanes) if k is None]
        waiting = False
        if free and len(latest) > len(running):
            ordered = {self._key(item): item for item in self.order(list(latest.values()))}
            done = running | self._finished | self._lost
            waiting = any(k not in ordered and k not in done for k in latest)
            latest = ordered
        for k, item in latest.items():
            if k in running or k in self._finished or k in self._lost:
                continue
            if k in self._retry_at:  # failed a moment ago: waits for fresh details
                waiting = True
                continue
            if len(running) >= width or not free:
                waiting = True
                break
            i = free.pop(0)
            lane = self.children[i]
            if lane.state is not _IDLE:
                lane.reset()  # every item starts from a fresh lane
            self._lanes[i], self._values[i] = k, item
            s = self._run(i, item)
            if not self._ended(i, s):
                running.add(k)
            elif s is _SUCCEEDED:
                free.insert(0, i)
            elif k not in self._lost:  # failed at once, to run again: not done yet
                waiting = True
                free.insert(0, i)
        out = self.outputs
        out["succeeded"], out["failed"] = len(self._finished), len(self._lost)
        out["running"] = len(running)
        if running or waiting or not self.inputs["complete"]:
            return _RUNNING
        self._restart = True
        return _FAILED if self._lost else _SUCCEEDED

    def order(self, items: list[Any]) -> list[Any]:
        """The listed ``items`` in the order free lanes take them, asked in a tick where
        a lane is free, after the running lanes were ticked (so a lane that just ended is
        free): as listed here; a subclass may put first what is best to do next (the
        exploration goal nearest to where an explorer is now, say) and leave out what
        must wait (it is not started in this tick, nor is the node done meanwhile)."""
        return items

    def _forget(self) -> None:
        for c in self.children:
            if c.state is not _IDLE:
                c.reset()
        self._lanes = [None] * len(self.children)
        self._values = [None] * len(self.children)
        self._finished.clear()
        self._lost.clear()
        self._restart = False

    def on_untick(self) -> None:
        for i, item in enumerate(self._lanes):
            if item is not None and self.children[i].state in _ACTIVE:
                self.children[i].untick()

    def on_reset(self) -> None:
        self._lanes = [None] * len(self.children)
        self._values = [None] * len(self.children)
        self._finished.clear()
        self._lost.clear()
        self._restart = False

    def utility(self) -> Utility:
        return parallel_utility([c.utility() for c in self.children])
