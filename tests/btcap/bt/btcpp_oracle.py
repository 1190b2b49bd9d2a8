"""The same BehaviorTree.CPP XML ticked in btcap and in BehaviorTree.CPP 4.8 (behaviortreepy).

Leaves are scripted: ``<Act name="a3"/>`` is a stateful action in BehaviorTree.CPP
(``on_start``/``on_running`` give the script's next result, ``on_halted`` logs a halt)
and a btcap leaf that logs a halt when unticked while running; ``<Cond>`` is a condition
(BehaviorTree.CPP cannot halt it, so no halt is logged). A leaf's k-th tick gives
``script[k % len(script)]``. Each run logs ``tick NAME`` / ``halt NAME`` in order.

btcap's run also watches for the moments a documented difference
(:data:`btcap.bt.files.btcpp_nodes.DIFFERENCES`) can start to show; the comparison stops
there (:func:`compare`), so everything before is compared exactly and nothing else is
excused.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import Any

import behaviortreepy as bt

from btcap import (
    AsyncSequenceWithMemory,
    LatchedIfThenElse,
    Leaf,
    Parallel,
    ParallelAll,
    Repeat,
    RepeatUntilSuccess,
    Sequence,
    SequenceWithMemory,
    State,
)
from btcap.bt.decorators import _Counting
from btcap.bt.files import loads_tree
from btcap.bt.invariants import check_halting, record_ticks
from btcap.bt.node import Node
from btcap.bt.registry import default_registry

_BT = {"S": bt.NodeStatus.SUCCESS, "F": bt.NodeStatus.FAILURE, "R": bt.NodeStatus.RUNNING}
_FROM_BT = {v: k for k, v in _BT.items()} | {bt.NodeStatus.SKIPPED: "K"}
_STATE = {"S": State.SUCCEEDED, "F": State.FAILED, "R": State.RUNNING}
_FROM_STATE = {State.SUCCEEDED: "S", State.FAILED: "F", State.ERROR: "E", State.SKIPPED: "K"}
_ACTIVE = (State.RUNNING, State.ASSIGNED, State.UNASSIGNED)

COMPOSITES = (
    "Sequence",
    "Fallback",
    "ReactiveSequence",
    "ReactiveFallback",
    "SequenceWithMemory",
    "AsyncSequence",
    "AsyncFallback",
    "Parallel",
    "WhileDoElse",
    "IfThenElse",
    "ParallelAll",
)
DECORATORS = (
    "Inverter",
    "ForceSuccess",
    "ForceFailure",
    "RetryUntilSuccessful",
    "Repeat",
    "KeepRunningUntilFailure",
    "RunOnce",
)
LEAVES = ("Act", "Cond", "AlwaysSuccess", "AlwaysFailure")


@dataclass
class El:
    """An XML element of a generated tree."""

    tag: str
    name: str
    attrs: dict[str, str] = field(default_factory=dict)
    children: list[El] = field(default_factory=list)
    script: str = ""

    def xml(self) -> str:
        attrs = "".join(f' {k}="{v}"' for k, v in {"name": self.name, **self.attrs}.items())
        if not self.children:
            return f"<{self.tag}{attrs}/>"
        inner = "".join(c.xml() for c in self.children)
        return f"<{self.tag}{attrs}>{inner}</{self.tag}>"

    def walk(self) -> list[El]:
        return [self, *(d for c in self.children for d in c.walk())]


def document(root: El) -> str:
    return f'<root BTCPP_format="4"><BehaviorTree ID="Main">{root.xml()}</BehaviorTree></root>'


def scripts_of(root: El) -> dict[str, str]:
    return {e.name: e.script for e in root.walk() if e.tag in ("Act", "Cond")}


def random_tree(rng: random.Random, max_depth: int = 4) -> El:
    """A random tree over every mapped node type; leaves named a0, a1, …."""
    counter = [0]

    def name() -> str:
        counter[0] += 1
        return f"n{counter[0]}"

    def leaf(cond: bool = False) -> El:
        roll = rng.random()
        if not cond and roll < 0.1:
            return El(rng.choice(("AlwaysSuccess", "AlwaysFailure")), name())
        script = "".join(rng.choice("SSFFRR") for _ in range(rng.randint(1, 4)))
        tag = "Cond" if cond or roll < 0.3 else "Act"
        return El(tag, name(), script=script)

    def node(depth: int) -> El:
        if depth >= max_depth or rng.random() < 0.2 + 0.15 * depth:
            return leaf()
        if rng.random() < 0.35:
            tag = rng.choice(DECORATORS)
            attrs = {
                "RetryUntilSuccessful": {"num_attempts": str(rng.choice((-1, 1, 2, 3)))},
                "Repeat": {"num_cycles": str(rng.choice((-1, 1, 2, 3)))},
                "RunOnce": {"then_skip": "false"},
            }.get(tag, {})
            return El(tag, name(), attrs, [node(depth + 1)])
        tag = rng.choice(COMPOSITES)
        if tag in ("WhileDoElse", "IfThenElse"):
            # The documented difference "action_result_kept": a stateful action that gave a
            # result is not run again by BehaviorTree.CPP until its parent resets it, and
            # these reset their condition only when they give a result. A condition leaf
            # is a condition node here, as in most real trees; the test shows the rest.
            first = node(depth + 1)
            if first.tag == "Act":
                first.tag = "Cond"
            kids = [first, *(node(depth + 1) for _ in range(rng.randint(1, 2)))]
            return El(tag, name(), children=kids)
        kids = [node(depth + 1) for _ in range(rng.randint(1, 4))]
        attrs = {}
        if tag == "Parallel":
            n = len(kids)
            attrs = {
                "success_count": str(rng.randint(-n - 1 if n > 1 else -1, n) or -1),
                "failure_count": "1",
            }
        elif tag == "ParallelAll":
            attrs = {"max_failures": str(rng.randint(-len(kids) - 1, len(kids)))}
        return El(tag, name(), attrs, kids)

    return node(0)


class _Script:
    """The scripts and the log of one btcap run (leaves read it through the class)."""

    current: _Script | None = None

    def __init__(self, scripts: dict[str, str]) -> None:
        self.scripts = scripts
        self.counts: dict[str, int] = {}
        self.log: list[str] = []

    def step(self, name: str) -> str:
        self.log.append(f"tick {name}")
        k = self.counts.get(name, 0)
        self.counts[name] = k + 1
        script = self.scripts[name]
        return script[k % len(script)]


class Act(Leaf):
    """A scripted action: logs its ticks, and its halts while running."""

    __slots__ = ()

    def on_tick(self) -> State:
        run = _Script.current
        assert run is not None
        return _STATE[run.step(self.name)]

    def on_untick(self) -> None:
        if self.state in _ACTIVE and _Script.current is not None:
            _Script.current.log.append(f"halt {self.name}")


class Cond(Act):
    """A scripted condition: BehaviorTree.CPP cannot see it halted, so neither logs it."""

    __slots__ = ()

    def on_untick(self) -> None:
        pass


def _progress(node: Node) -> bool:
    """Whether an untick of ``node`` keeps something a BehaviorTree.CPP halt forgets."""
    if isinstance(node, Parallel):
        return node._pending is not None and node._ok + node._bad > 0
    if isinstance(node, _Counting):
        return node.count > 0
    if isinstance(node, ParallelAll):
        return bool(node._finished)
    if isinstance(node, LatchedIfThenElse):
        return node._branch > 0
    if isinstance(node, Sequence) and not isinstance(
        node, (SequenceWithMemory, AsyncSequenceWithMemory)
    ):
        return node._current > 0
    from btcap.bt.composites import Fallback

    return isinstance(node, Fallback) and node._current > 0


#: Root ticks in one tickOnce taken for a tree that keeps waking itself up: one whose
#: reactive parent restarts a yielding child every tick never returns, in either.
WAKING_FOREVER = 500
#: What :func:`compare` reports for such a tree (BehaviorTree.CPP is not asked: it hangs).
WAKES_FOREVER = "wakes forever (tickOnce never returns in either)"


class WakingForever(Exception):
    """btcap's tick_once went past WAKING_FOREVER root ticks."""


class BtcapRun:
    """The XML loaded by btcap's loader; ticks report the root, the log and differences.

    ``once``: each tick is :meth:`Tree.tick_once <btcap.bt.tree.Tree.tick_once>`
    (BehaviorTree.CPP's ``tickOnce``), else :meth:`Tree.tick` (its ``tickExactlyOnce``);
    every root tick inside it is checked and watched for differences on its own.
    """

    def __init__(self, xml: str, scripts: dict[str, str], once: bool = False) -> None:
        self.once = once
        self.root_ticks = 0
        reg = default_registry(plugins=False)
        reg.register(Act)
        reg.register(Cond)
        self.run = _Script(scripts)
        self.tree = loads_tree(xml, "xml", reg)
        self.now: set[str] = set()  # differences showing in this tick
        self.later: set[str] = set()  # differences that may show from the next tick
        self.decided: list[Parallel] = []  # Parallels that gave a result in this tick
        self.tree.observe(self._watch)
        self._tick = self.tree.tick
        self.tree.tick = self._root_tick  # type: ignore[method-assign]  # what tick_once calls

    def _watch(self, node: Node, old: State, new: State) -> None:
        parent = node.parent_node
        if new is State.ERROR and "its condition was skipped" in str(node.error):
            self.now.add("skipped_condition")  # seen even if a retry resets it at once
        if isinstance(node, Parallel) and new in (State.SUCCEEDED, State.FAILED):
            self.decided.append(node)
        if new is State.PAUSED and old in _ACTIVE and _progress(node):
            self.later.add("halt_keeps_progress")
        if old in _ACTIVE and isinstance(parent, RepeatUntilSuccess) and new is State.FAILED:
            limit = parent.options["max_attempts"]
            if limit is None or parent.count + 1 < limit:
                self.now.add("loop_after_running")
        if old in _ACTIVE and isinstance(parent, Repeat) and new is State.SUCCEEDED:
            times = parent.options["times"]
            if times == -1 or parent.count + 1 < times:
                self.now.add("loop_after_running")

    def tick(self) -> tuple[str, list[str]]:
        _Script.current = self.run
        self.run.log = []
        self.root_ticks = 0
        try:
            state = self.tree.tick_once() if self.once else self.tree.tick()
        finally:
            _Script.current = None
        return _FROM_STATE.get(state, "R"), self.run.log

    def _root_tick(self) -> State:
        """One root tick: checked, and watched for the differences it may show."""
        self.now |= self.later  # one that may show from this tick on, within a tick_once
        self.root_ticks += 1
        if self.root_ticks > WAKING_FOREVER:
            raise WakingForever
        state, ticked = record_ticks(self.tree, self._tick)
        check_halting(self.tree, ticked)
        seen = {id(n) for n in ticked}
        done = (State.SUCCEEDED, State.FAILED)
        # A Parallel that gave a result: seen changing to it (it may have been reset since
        # by a Retry), or still holding it (a result repeated causes no change to watch).
        self.decided += [n for n in ticked if isinstance(n, Parallel) and n.state in done]
        for n in self.decided:
            if sum(id(c) in seen for c in n.children) > 1:
                self.now.add("parallel_decides_per_child")
        self.decided = []
        # A SequenceWithMemory that failed or was halted past its first child keeps its
        # place in both, until btcap resets it (a retry, a Parallel starting over).
        kept = (State.FAILED, State.ERROR, State.PAUSED)
        for n in self.tree.root.walk():
            if isinstance(n, AsyncSequenceWithMemory) and n._current > 0 and n.state in kept:
                up = n.parent_node
                while up is not None:
                    if isinstance(up, (Parallel, _Counting)):
                        self.later.add("memory_reset_by_retry")
                    up = up.parent_node
        return state

    def halt(self) -> list[str]:
        _Script.current = self.run
        self.run.log = []
        try:
            self.tree.untick()
        finally:
            _Script.current = None
        return self.run.log

    def reset(self) -> None:
        """:meth:`Tree.reset <btcap.bt.tree.Tree.reset>`: every node starts over."""
        _Script.current = self.run
        try:
            self.tree.reset()
        finally:
            _Script.current = None


class BtcppRun:
    """The XML in BehaviorTree.CPP 4.8, with the same scripted leaves."""

    def __init__(self, xml: str, scripts: dict[str, str], once: bool = False) -> None:
        self.once = once
        self.scripts = scripts
        self.counts: dict[str, int] = {}
        self.log: list[str] = []
        factory = bt.BehaviorTreeFactory()
        factory.register_simple_stateful_action("Act", self._step, self._step, self._halted)
        factory.register_simple_condition("Cond", self._step)
        self.tree = factory.create_tree_from_text(xml)

    def _step(self, node: Any) -> Any:
        name = node.name()
        self.log.append(f"tick {name}")
        k = self.counts.get(name, 0)
        self.counts[name] = k + 1
        script = self.scripts[name]
        return _BT[script[k % len(script)]]

    def _halted(self, node: Any) -> None:
        self.log.append(f"halt {node.name()}")

    def tick(self) -> tuple[str, list[str]]:
        self.log = []
        tick = self.tree.tick_once if self.once else self.tree.tick_exactly_once
        return _FROM_BT[tick()], self.log

    def halt(self) -> list[str]:
        self.log = []
        self.tree.halt_tree()
        return self.log


@dataclass
class Outcome:
    """How far one tree was compared, and the first mismatch if any."""

    ticks: int  # ticks compared exactly
    stopped_by: str | None  # the documented difference that ended the comparison
    mismatch: str | None


def compare(root: El, ticks: int = 10, once: bool = False) -> Outcome:
    """Tick by tick in both, by ``tickExactlyOnce`` or (``once``) by ``tickOnce``."""
    xml = document(root)
    scripts = scripts_of(root)
    try:
        theirs = BtcppRun(xml, scripts, once)
    except RuntimeError as exc:  # e.g. "A ReactiveSequence cannot have more than one async child"
        return Outcome(0, f"refused by BehaviorTree.CPP: {exc}", None)
    mine = BtcapRun(xml, scripts, once)
    for t in range(ticks):
        try:
            got = mine.tick()
        except WakingForever:
            return Outcome(t, WAKES_FOREVER, None)
        if mine.now:  # before BehaviorTree.CPP's tick, which may not return then (tickOnce)
            return Outcome(t, sorted(mine.now)[0], None)
        want = theirs.tick()
        if got != want:
            return Outcome(t, None, f"tick {t}: btcap {got} BehaviorTree.CPP {want}\n{xml}")
        if mine.later:
            return Outcome(t + 1, sorted(mine.later)[0], None)
    got_halt, want_halt = mine.halt(), theirs.halt()
    if sorted(got_halt) != sorted(want_halt):
        return Outcome(ticks, None, f"halt: btcap {got_halt} BehaviorTree.CPP {want_halt}\n{xml}")
    return Outcome(ticks, None, None)
