"""Debug mode: a node caught in a restart loop is named once, with the cause and the fix;
legitimate pre-emption is not; off, the check costs nothing (the suite runs with it on)."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
import warnings
from collections.abc import Callable

import anyio
import pytest

from btcap import (
    Action,
    AlwaysRunning,
    AlwaysSuccess,
    Condition,
    IfThenElse,
    Leaf,
    Node,
    Parallel,
    ReactiveFallback,
    ReactiveSequence,
    Repeat,
    RestartLoopWarning,
    RunOnce,
    Sequence,
    State,
    Subtree,
    Tree,
    TreeTimeout,
    Wait,
)
from btcap.actors import ManualClock
from btcap.bt.state import BtcapWarning

S, R = State.SUCCEEDED, State.RUNNING
STEP = 0.25  # a tick period that adds up exactly in floating point


class Starts(Leaf):
    """Runs for ever; counts how often it was started (from idle or paused)."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.starts = 0

    def on_tick(self) -> State:
        if self.state is not R:
            self.starts += 1
        return R


def newcomer(work: Node, sequence: type[Node] = ReactiveSequence) -> Node:
    """The tree of the report: a check, a finite Repeat over a Wait, then the work."""
    return sequence(
        "s",
        children=[
            Condition(lambda: True, "check"),
            Repeat("rep", times=1, children=[Wait("w", seconds=STEP)]),
            work,
        ],
    )


async def ticks(tree: Tree, clock: ManualClock, n: int) -> list[State]:
    out = []
    for _ in range(n):
        out.append(tree.tick())
        await clock.advance(STEP)
    return out


async def test_the_newcomers_hang_is_named_within_a_few_ticks_and_once() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        act = Starts("act")
        tree = Tree(newcomer(act), clock=clock)
        assert tree.debug  # on in tests (conftest)
        await ticks(tree, clock, 7)  # act started at ticks 2, 4, 6: restarted twice
        with pytest.warns(RestartLoopWarning) as caught:
            tree.tick()  # the third restart
        assert len(caught) == 1
        assert str(caught[0].message) == (
            "node 's/act' (Starts) was halted and started again 3 times in a row without "
            "finishing: its parent 's' (ReactiveSequence) ticks the earlier child 's/rep' again, "
            "which starts over after finishing and halts this one; use Sequence, "
            "which resumes at the running child, or make 's/rep' keep its result (e.g. wrap "
            "it in RunOnce)"
        )
        assert caught[0].filename == __file__  # points at the caller of Tree.tick
        assert act.starts == 4
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            await ticks(tree, clock, 40)  # once per node
        assert act.starts == 24


def run_once_fix() -> Node:
    once = RunOnce("once", children=[Repeat("rep", times=1, children=[Wait("w", seconds=STEP)])])
    return ReactiveSequence("s", children=[Condition(lambda: True, "check"), once, Starts("act")])


@pytest.mark.parametrize(
    "fixed",
    [lambda: newcomer(Starts("act"), Sequence), run_once_fix],
    ids=["memory", "run-once"],
)
async def test_the_fixes_it_suggests_run_the_work_without_a_warning(
    fixed: Callable[[], Node],
) -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(fixed(), clock=clock)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            await ticks(tree, clock, 30)
        act = tree.find("s/act")
        assert isinstance(act, Starts)
        assert act.state is R
        assert act.starts == 1


async def test_a_run_with_a_limit_warns_then_stops_the_loop_naming_what_runs() -> None:
    never = asyncio.Event()

    async def work() -> None:
        await never.wait()

    with anyio.fail_after(5):
        clock = ManualClock()
        tree = Tree(newcomer(Action(work, "act")), clock=clock)
        warned = pytest.warns(RestartLoopWarning, match="node 's/act' \\(Action\\)")
        stopped = pytest.raises(TreeTimeout, match="time limit of 60 s")
        async with clock.autojump():
            with warned, stopped as err:
                await tree.run(1 / STEP, timeout_s=60)
        assert err.value.running == ("s/rep/w",)
        await tree.shutdown()


async def test_only_the_topmost_node_of_a_looping_branch_is_named() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        work = Sequence("work", children=[Starts("a"), Starts("b")])
        tree = Tree(newcomer(work), clock=clock)
        with pytest.warns(RestartLoopWarning) as caught:
            await ticks(tree, clock, 40)
        assert [str(w.message).split(" was ")[0] for w in caught] == ["node 's/work' (Sequence)"]


async def test_a_loop_inside_a_subtree_is_named_when_the_outer_tree_ticks() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        inner = Tree(newcomer(Starts("act")), debug=False)
        tree = Tree(ReactiveSequence("root", children=[Subtree(inner, "sub")]), clock=clock)
        with pytest.warns(RestartLoopWarning, match="node 's/act' \\(Starts\\)"):
            await ticks(tree, clock, 12)
        quiet = Tree(
            ReactiveSequence("root", children=[Subtree(Tree(newcomer(Starts("act"))), "sub")])
        )
        quiet.debug = False  # the tree that ticks decides, for its subtrees too
        quiet.clock = clock = ManualClock()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            await ticks(quiet, clock, 12)


async def test_pre_emption_that_lets_the_work_run_is_not_a_loop() -> None:
    """A patrol pre-empted by a recharge again and again: it runs for many ticks between."""
    with anyio.fail_after(5):
        clock = ManualClock()
        battery = {"low": False}
        patrol = Starts("patrol")
        root = ReactiveFallback(
            "root",
            children=[
                ReactiveSequence(
                    "recharge",
                    children=[
                        Condition(lambda: battery["low"], "low"),
                        Wait("charge", seconds=STEP),
                    ],
                ),
                patrol,
            ],
        )
        tree = Tree(root, clock=clock)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            for _ in range(6):
                await ticks(tree, clock, 5)
                battery["low"] = True
                await ticks(tree, clock, 1)
                battery["low"] = False
        assert patrol.starts == 6


async def test_halts_for_other_reasons_every_tick_are_not_a_loop() -> None:
    with anyio.fail_after(5):
        clock = ManualClock()
        flip = {"on": False}

        def toggle() -> bool:
            flip["on"] = not flip["on"]
            return flip["on"]

        branch = Starts("branch")
        raced = Starts("raced")
        root = Parallel(
            "root",
            children=[
                IfThenElse("if", children=[Condition(toggle, "cond"), branch]),
                Repeat(
                    "again",
                    times=-1,
                    children=[
                        Parallel(
                            "race", success_threshold=1, children=[AlwaysSuccess("quick"), raced]
                        )
                    ],
                ),
            ],
        )
        tree = Tree(root, clock=clock)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            await ticks(tree, clock, 20)
        assert branch.starts == 10


def test_off_it_watches_nothing() -> None:
    off = Tree(newcomer(AlwaysRunning("act")), debug=False)
    assert not off.debug
    assert all(n._watch is None for n in off.nodes())
    on = Tree(newcomer(AlwaysRunning("act")), debug=True)
    assert all(n._watch is not None for n in on.nodes())
    on.debug = False
    assert all(n._watch is None for n in on.nodes())
    assert issubclass(RestartLoopWarning, BtcapWarning)
    assert issubclass(BtcapWarning, UserWarning)


@pytest.mark.parametrize(("value", "on"), [("1", True), ("yes", True), ("0", False), ("", False)])
def test_the_environment_variable_turns_it_on(
    monkeypatch: pytest.MonkeyPatch, value: str, on: bool
) -> None:
    monkeypatch.setenv("BTCAP_DEBUG", value)
    assert Tree(AlwaysSuccess()).debug is on
    monkeypatch.delenv("BTCAP_DEBUG")
    assert Tree(AlwaysSuccess()).debug is bool(sys.flags.dev_mode)
    assert Tree(AlwaysSuccess(), debug=True).debug


def test_python_development_mode_turns_it_on() -> None:
    env = {k: v for k, v in os.environ.items() if k != "BTCAP_DEBUG"}
    code = "from btcap import AlwaysSuccess, Tree; print(Tree(AlwaysSuccess()).debug)"
    done = subprocess.run(
        [sys.executable, "-X", "dev", "-c", code],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert done.stdout.strip() == "True"  # without -X dev: the test above
