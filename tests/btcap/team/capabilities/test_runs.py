"""Building an implementation's subtree for an award stays off the event loop on a real
clock: a file-backed implementation reads, parses and builds its tree afresh for every
run (a 300-node tree costs ~40 ms of CPU, a 2000-node one ~300 ms), which on the loop
holds up the robot's heartbeats. Judged by the thread each run was built in, not by time."""

from __future__ import annotations

import threading
import warnings

import anyio
from capfixtures import team, tick_until, until

from btcap import AlwaysSuccess, Leaf, ReactiveSequence, Sequence, State
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation

BARE = CapabilityInterface("Bare")


class _Mark(Leaf):
    """Says which root it ran under, so a test knows which built tree a run used."""

    def __init__(self, ran: list[int]) -> None:
        super().__init__("mark")
        self.ran = ran

    def on_tick(self) -> State:
        assert self.parent_node is not None
        self.ran.append(id(self.parent_node))
        return State.SUCCEEDED


class _Built:
    """Which thread built each root node (the implementation's own build function)."""

    def __init__(self) -> None:
        self.thread: dict[int, int] = {}
        self.ran: list[int] = []

    def __call__(self) -> Sequence:
        steps = [AlwaysSuccess(f"step{i}") for i in range(5)]
        root = Sequence("work", children=[*steps, _Mark(self.ran)])
        self.thread[id(root)] = threading.get_ident()
        return root


async def test_every_awarded_run_was_built_off_the_loop_thread() -> None:
    loop_thread = threading.get_ident()
    built = _Built()
    with anyio.fail_after(30):
        async with team(real_time=True) as t:
            a = await t.add("a")
            impl = Implementation("bare-b", BARE, built)
            b = await t.add("b", [impl])
            await t.converged(BARE.identity)
            hosted = b.mission_control.host.hosted
            runs = b.mission_control.executor.runs
            for _ in range(4):  # four runs in turn: the first, then each from a fresh spare
                # (awards in turn, each once the last one's spare is built: however slow
                # the machine, an award then finds a spare built in the thread)
                await until(lambda: runs.ready(impl), "b's spare to be built")
                node = BARE.node_type()("bare")
                tree = a.mission(ReactiveSequence("root", children=[node]))
                await tick_until(tree, lambda s: s is not State.RUNNING)
                assert node.state is State.SUCCEEDED
                assert node.assignments == ["b"]
                await tree.shutdown()
                await until(lambda: not hosted, "b's run to end")
            done = set(built.ran)
            assert len(done) == 4
            on_loop = [r for r in done if built.thread[r] == loop_thread]
            assert on_loop == [], f"{len(on_loop)} of 4 runs built on the loop thread"


async def test_on_a_virtual_clock_runs_are_built_inline_as_before() -> None:
    """--fast stays reproducible: no worker threads decide what is ready when."""
    loop_thread = threading.get_ident()
    built = _Built()
    with anyio.fail_after(30):
        async with team() as t:
            a = await t.add("a")
            await t.add("b", [Implementation("bare-b", BARE, built)])
            await t.converged(BARE.identity)
            node = BARE.node_type()("bare")
            tree = a.mission(ReactiveSequence("root", children=[node]))
            assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
            await tree.shutdown()
    assert built.thread
    assert set(built.thread.values()) == {loop_thread}


class _LoopOnly:
    """A build that works on the loop's thread only (say, one that needs the running
    loop): it fails in a worker thread."""

    def __init__(self) -> None:
        self.loop_thread = threading.get_ident()

    def __call__(self) -> Sequence:
        if threading.get_ident() != self.loop_thread:
            raise RuntimeError("needs the loop's thread")
        return Sequence("work", children=[AlwaysSuccess("step")])


async def test_a_build_that_fails_in_a_thread_is_warned_once_and_counted() -> None:
    def told(caught: list[warnings.WarningMessage]) -> list[str]:
        return [str(w.message) for w in caught if "'bare-b'" in str(w.message)]

    with anyio.fail_after(30), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        async with team(real_time=True) as t:
            a = await t.add("a")
            b = await t.add("b", [Implementation("bare-b", BARE, _LoopOnly())])
            await t.converged(BARE.identity)
            await until(lambda: bool(told(caught)), "b's warning")
            hosted = b.mission_control.host.hosted
            for _ in range(3):  # each award builds on the loop, and works
                node = BARE.node_type()("bare")
                tree = a.mission(ReactiveSequence("root", children=[node]))
                assert await tick_until(tree, lambda s: s is not State.RUNNING) is State.SUCCEEDED
                assert node.assignments == ["b"]
                await tree.shutdown()
                await until(lambda: not hosted, "b's run to end")
            assert b.mission_control.stats.built_on_loop == 3
            assert b.mission_control.executor.runs is not None
            assert b.mission_control.executor.runs.built_on_loop == 3
    (message,) = told(caught)  # once, however many awards
    assert "RuntimeError: needs the loop's thread" in message
    assert "worker thread" in message


class _Held:
    """Builds in worker threads wait until released, counting how many wait at once."""

    def __init__(self) -> None:
        self.loop_thread = threading.get_ident()
        self.lock = threading.Lock()
        self.release = threading.Event()
        self.active = 0
        self.peak = 0

    def __call__(self) -> Sequence:
        if threading.get_ident() != self.loop_thread:
            with self.lock:
                self.active += 1
                self.peak = max(self.peak, self.active)
            try:
                self.release.wait(30)
            finally:
                with self.lock:
                    self.active -= 1
        return Sequence("work", children=[AlwaysSuccess("step")])


async def test_spares_are_built_one_thread_at_a_time() -> None:
    """A robot with four implementations builds a spare of each at its start: one at a
    time, the others queued, not four threads taking every core."""
    held = _Held()
    impls = [Implementation(f"bare-{i}", BARE, held) for i in range(4)]
    try:
        with anyio.fail_after(30):
            async with team(real_time=True) as t:
                b = await t.add("b", impls)
                runs = b.mission_control.executor.runs
                assert runs is not None

                def started() -> bool:  # (the first one's thread may run after the rest queued)
                    return held.peak >= 2 or (held.active == 1 and runs.queued == 3)

                await until(started, "builds to start")
                assert (held.peak, held.active) == (1, 1)
                held.release.set()
                await until(lambda: all(runs.ready(i) for i in impls), "every spare")
                assert held.peak == 1
    finally:
        held.release.set()
