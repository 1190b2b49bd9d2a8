"""Ticking a tree at a rate on its clock until a result, or until a limit stops it."""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Coroutine
from typing import TYPE_CHECKING, Any, Protocol

from btcap.actors import Clock, ManualClock
from btcap.bt.node import Node
from btcap.bt.state import ACTIVE, ENDED, State, TreeError, TreeTimeout

if TYPE_CHECKING:
    from btcap.actors import ActorSystem, TimeSource

__all__ = [
    "WAKES_IN_A_ROW",
    "Alarm",
    "Runnable",
    "nudge",
    "nudge_holder",
    "run_tree",
    "running_paths",
    "start_task",
    "tick_once",
]

#: Ticks at once, in a row, that :func:`run_tree` makes for nodes that ask for them.
WAKES_IN_A_ROW = 10_000


class Alarm:
    """How news from outside reaches a tree's run: :func:`nudge` sets ``nudged`` and rings
    ``future``, the sleep of :func:`run_tree` between two ticks; a tree ticked by another
    (a Subtree's, an implementation's in a robot's slot) passes it on to ``outer``."""

    __slots__ = ("future", "nudged", "outer", "running")

    def __init__(self) -> None:
        self.nudged = False
        self.running = False
        self.future: asyncio.Future[None] | None = None
        self.outer: Any = None


def nudge(tree: Any) -> None:
    """Tick ``tree`` soon, ahead of its period: there is news for one of its nodes (a ROS
    goal answered). On the event loop's thread (hand over with ``call_soon_threadsafe``).
    The tree that runs it (itself, or the one that ticks it) ticks once at once, however
    many nudges came meanwhile; its periodic ticks keep their times."""
    alarm: Alarm = tree.alarm
    while not alarm.running and alarm.outer is not None:
        alarm = alarm.outer.alarm
    alarm.nudged = True
    future = alarm.future
    if future is not None and not future.done():
        future.set_result(None)


def nudge_holder(node: Node) -> None:
    """:func:`nudge` the tree that holds ``node`` (news for it came by message: a result,
    an assignment); nothing for a node in no tree."""
    tree = node._tree
    if tree is not None and getattr(tree, "alarm", None) is not None:
        nudge(tree)


class Runnable(Protocol):
    """What :func:`run_tree` needs of a tree; :class:`~btcap.bt.tree.Tree` is one."""

    name: str
    root: Node
    clock: TimeSource
    woken: bool
    alarm: Alarm

    def tick(self) -> State: ...
    def untick(self) -> None: ...


async def run_tree(
    tree: Runnable,
    rate_hz: float,
    until: Callable[[State], bool] | None,
    max_ticks: int | None,
    timeout_s: float | None,
    wake: bool = False,
) -> State:
    """:meth:`Tree.run <btcap.bt.tree.Tree.run>`: tick drift-free at ``rate_hz`` until
    ``until(state)`` (default: a result); at a limit, untick and raise TreeTimeout.

    With ``wake``, a tick after which a node asked to be ticked again (``tree.woken``)
    is followed at once by the next, as BehaviorTree.CPP's ``tickWhileRunning`` cuts its
    sleep short; the period counts from there. After :data:`WAKES_IN_A_ROW` such ticks the
    period is kept once, so that a tree that always asks (a ``Repeat`` forever of a child
    that succeeds at once) still lets clock time pass and the run reach its limits.

    A :func:`nudge` (news from outside: a ROS goal answered) ticks the tree at once,
    an extra tick that leaves the periodic ticks' times as they were."""
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    if max_ticks is not None and max_ticks < 1:
        raise ValueError(f"max_ticks must be >= 1 or None, got {max_ticks}")
    if timeout_s is not None and not timeout_s > 0:
        raise ValueError(f"timeout_s must be > 0 or None, got {timeout_s}")
    stop = until or (lambda s: s in ENDED)
    clock = tree.clock
    period = 1.0 / rate_hz
    deadline = clock.now()
    end = None if timeout_s is None else deadline + timeout_s
    ticks = woken = 0
    early = False
    alarm = tree.alarm
    alarm.running = True
    try:
        while True:
            state = tree.tick()
            ticks += 1
            if stop(state):
                return state
            if max_ticks is not None and ticks >= max_ticks:
                raise _halt(tree, "max_ticks", max_ticks, state, ticks)
            if wake and tree.woken and woken < WAKES_IN_A_ROW:
                tree.woken = False
                woken += 1
                deadline = clock.now()  # the next tick now, yet through the loop
            elif not early:  # a nudged tick was an extra: the period's deadline stands
                woken = 0
                deadline += period
            now = clock.now()
            if deadline < now - period:  # fell far behind: skip, don't burst
                deadline = now
            if end is not None and timeout_s is not None and deadline > end:
                await clock.sleep_until(end)  # not a tick later: the limit is the limit
                raise _halt(tree, "timeout_s", timeout_s, state, ticks)
            early = await _sleep_until(alarm, clock, deadline)
    finally:
        alarm.running = False
        alarm.nudged = False


async def _sleep_until(alarm: Alarm, clock: TimeSource, deadline: float) -> bool:
    """Sleep until ``deadline`` on ``clock``, or less if nudged: whether it was."""
    delay = deadline - clock.now()
    if alarm.nudged or delay <= 0:  # news came during the tick, or the period is over
        alarm.nudged = False
        await asyncio.sleep(0)  # through the loop, never holding it
        return delay > 0
    loop = asyncio.get_running_loop()
    future = alarm.future = loop.create_future()
    handle: Any
    if isinstance(clock, Clock):  # asyncio.sleep's own way, with the future ours to ring
        handle = loop.call_later(clock.to_wall(delay), _ring, future)
    elif isinstance(clock, ManualClock):
        handle = clock.call_later(delay, _ring, future)
    else:  # a clock of its own: it sleeps, deaf to nudges
        alarm.future = None
        await clock.sleep_until(deadline)
        return False
    try:
        await future
    finally:
        handle.cancel()
        alarm.future = None
    early = alarm.nudged and clock.now() < deadline
    alarm.nudged = False
    return early


def _ring(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


def tick_once(tree: Runnable) -> State:
    """BehaviorTree.CPP's ``tickOnce``: tick, and tick again at once while the tree is
    running and a node asked for it since (a request left by a tick that ended the run
    stays for the next call, as BehaviorTree.CPP's wake-up signal does). As there, a tree
    that always asks (a ``Repeat`` forever of a child that succeeds at once) never returns."""
    state = tree.tick()
    while state is State.RUNNING and tree.woken:
        tree.woken = False
        state = tree.tick()
    return state


def start_task(
    tree: Runnable, coro: Coroutine[Any, Any, Any], name: str | None
) -> asyncio.Task[Any]:
    """A node's background task: on the tree's actor system, else on the running loop."""
    system: ActorSystem | None = getattr(tree, "system", None)
    if system is not None:
        return system.start_task(coro, name=name)
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        coro.close()
        raise TreeError(f"tree {tree.name!r}: background work needs a running event loop") from None
    return loop.create_task(coro, name=name)


def _halt(tree: Runnable, limit: str, value: float, state: State, ticks: int) -> TreeTimeout:
    """Untick the tree at a limit; the error to raise, naming the work it was doing."""
    running = tuple(running_paths(tree.root))
    tree.untick()
    return TreeTimeout(tree.name, limit, value, running=running, state=state, ticks=ticks)


def running_paths(root: Node) -> list[str]:
    """Paths of the nodes doing the work of a running tree: active nodes without an
    active child (inside a Subtree, below the Subtree's path)."""
    out: list[str] = []

    def visit(node: Node, prefix: str) -> None:
        if node.state not in ACTIVE:
            return
        inner = getattr(node, "inner", None)  # a Subtree: its tree's nodes are its own
        below = inner.root.children if inner is not None else node.children
        busy = [c for c in below if c.state in ACTIVE]
        if not busy:
            out.append(prefix + node.name)
        for c in busy:
            visit(c, f"{prefix}{node.name}/")

    visit(root, "")
    return out
