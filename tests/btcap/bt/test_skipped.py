"""BehaviorTree.CPP's SKIPPED in btcap: ``_skipIf``, ``_while`` and ``RunOnce``'s default
``then_skip``, and how each BehaviorTree.CPP control node and decorator treats a skipped
child. Every tree here runs in btcap and in BehaviorTree.CPP 4.8 (behaviortreepy), in
both tick modes, and must agree on each tick's result, the leaves ticked and halted and
the blackboard; the expected results are written out too (read off BehaviorTree.CPP)."""

from __future__ import annotations

import random
import warnings

import pytest
from structlog.testing import capture_logs

from btcap import State
from btcap.bt.files import loads_tree
from btcap.bt.files.btcpp_nodes import DIFFERENCES
from btcap.bt.registry import default_registry
from btcap.bt.scripting.values import to_text

pytest.importorskip(
    "behaviortreepy",
    reason="behaviortreepy (BehaviorTree.CPP 4.8) has wheels only for CPython 3.11 on x86-64 Linux",
)

import script_oracle
from btcpp_oracle import WAKES_FOREVER, BtcapRun, BtcppRun, random_tree


def _xml(body: str) -> str:
    return f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>'


def _both(body: str, scripts: dict[str, str], ticks: int) -> list[str]:
    """Each tick's result in both, in both tick modes, checked equal; btcap's results."""
    xml = _xml(body)
    results: dict[bool, list[str]] = {}
    for once in (False, True):
        mine, theirs = BtcapRun(xml, scripts, once), BtcppRun(xml, scripts, once)
        got: list[str] = []
        for t in range(ticks):
            a, b = mine.tick(), theirs.tick()
            assert a == b, f"tick {t} (tickOnce={once}): btcap {a}, BehaviorTree.CPP {b}"
            board = theirs.tree.root_blackboard()
            want = {k: board.get_string(k) for k in board.get_keys()}
            have = {k: to_text(v) for k, v in mine.tree.blackboard.outputs.items() if v is not None}
            assert have == want, f"tick {t} (tickOnce={once}): btcap {have}, BT.CPP {want}"
            got.append(a[0])
        results[once] = got
    return results[False]


# Each: the body, the leaves' scripts, the results of tickExactlyOnce (K: SKIPPED).
RULES = {
    "skipIf passes a node over, post conditions do not run": (
        '<Sequence><Script code="x := 1; p := 0"/>'
        '<Act name="a" _skipIf="x == 1" _post="p += 1"/><Cond name="c"/></Sequence>',
        {"a": "F", "c": "S"},
        "SS",
    ),
    "a Sequence of skipped children is skipped, so is the root": (
        '<Sequence><AlwaysFailure _skipIf="true"/><Cond name="c" _skipIf="true"/></Sequence>',
        {"c": "F"},
        "KK",
    ),
    "a Fallback passes skipped children over": (
        '<Fallback><Cond name="a" _skipIf="true"/><Cond name="b"/>'
        '<AlwaysFailure _skipIf="true"/></Fallback>',
        {"a": "S", "b": "FS"},
        "FS",
    ),
    "while false before the start skips": (
        '<Sequence><Script code="n := 0"/><Act name="a" _while="n > 0"/></Sequence>',
        {"a": "S"},
        "SS",
    ),
    "while turning false halts the running node and runs _onHalted": (
        '<Sequence><Script code="n := 0; h := 0"/><ReactiveSequence><Script code="n += 1"/>'
        '<Act name="a" _while="n &lt; 3" _onHalted="h := n"/></ReactiveSequence></Sequence>',
        {"a": "R"},
        "RRSRR",
    ),
    "reactive nodes pass skipped children over, all skipped is skipped": (
        '<ReactiveFallback><Cond name="a" _skipIf="true"/>'
        '<ReactiveSequence><Cond name="b" _skipIf="true"/><AlwaysSuccess _skipIf="true"/>'
        '</ReactiveSequence><Act name="c"/></ReactiveFallback>',
        {"a": "S", "b": "S", "c": "RF"},
        "RFRF",
    ),
    "Parallel: skipped children count for a negative success_count": (
        '<Parallel success_count="-1" failure_count="1"><Act name="a"/>'
        '<Cond name="b" _skipIf="true"/></Parallel>',
        {"a": "RS"},
        "RSRS",
    ),
    "Parallel of skipped children is skipped": (
        '<Parallel success_count="1" failure_count="1"><Act name="a" _skipIf="true"/>'
        '<Cond name="b" _skipIf="true"/></Parallel>',
        {"a": "S", "b": "S"},
        "KK",
    ),
    "ParallelAll finishes when the rest is skipped": (
        '<ParallelAll max_failures="1"><Act name="a"/><Act name="b" _skipIf="true"/></ParallelAll>',
        {"a": "RF", "b": "S"},
        "RFRF",
    ),
    "decorators: Inverter and ForceSuccess pass SKIPPED, KeepRunning makes it RUNNING": (
        '<Sequence><Inverter><Cond name="a" _skipIf="true"/></Inverter>'
        '<ForceSuccess><Cond name="b" _skipIf="true"/></ForceSuccess>'
        '<KeepRunningUntilFailure><Cond name="c" _skipIf="true"/></KeepRunningUntilFailure>'
        "</Sequence>",
        {"a": "S", "b": "S", "c": "S"},
        "RR",
    ),
    "Repeat and RetryUntilSuccessful pass SKIPPED and keep their count": (
        '<Sequence><Script code="n := 0"/><Repeat num_cycles="3">'
        '<Sequence><Script code="n += 1"/><Cond name="a" _skipIf="n == 2"/></Sequence>'
        '</Repeat><RetryUntilSuccessful num_attempts="2"><Cond name="b" _skipIf="n &gt; 3"/>'
        "</RetryUntilSuccessful></Sequence>",
        {"a": "S", "b": "F"},
        "RRRFR",
    ),
    "RunOnce without then_skip is skipped after its run": (
        '<Sequence><RunOnce><Cond name="a"/></RunOnce><Cond name="b"/></Sequence>',
        {"a": "S", "b": "S"},
        "SSS",
    ),
    "AsyncSequence yields after an instant child past a skipped one": (
        '<AsyncSequence><Cond name="a" _skipIf="true"/><Cond name="b"/><Cond name="c"/>'
        "</AsyncSequence>",
        {"a": "S", "b": "S", "c": "S"},
        "RSRS",
    ),
    "SequenceWithMemory resumes at a failed child past skipped ones, not skipped then": (
        '<Sequence><Script code="k := 0"/><SequenceWithMemory><Cond name="a" _skipIf="true"/>'
        '<Act name="b" _skipIf="k == 1"/><Script code="k := 1"/></SequenceWithMemory></Sequence>',
        {"a": "S", "b": "F"},
        "FFF",
    ),
    "IfThenElse: a skipped branch makes it skipped": (
        '<IfThenElse><Cond name="c"/><Act name="a" _skipIf="true"/><Act name="b"/></IfThenElse>',
        {"c": "SF", "a": "S", "b": "S"},
        "KSKS",
    ),
    "WhileDoElse: a skipped branch makes it skipped": (
        '<WhileDoElse><Cond name="c"/><Act name="a"/><Act name="b" _skipIf="true"/></WhileDoElse>',
        {"c": "SF", "a": "R", "b": "S"},
        "RKRK",
    ),
}


@pytest.mark.parametrize("rule", list(RULES))
def test_each_rule_agrees_with_behaviortree_cpp(rule: str) -> None:
    body, scripts, want = RULES[rule]
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert "".join(_both(body, scripts, len(want))) == want


def test_a_skipped_root_ends_a_run() -> None:
    t = loads_tree(_xml('<AlwaysSuccess _skipIf="true"/>'), "xml", default_registry())
    assert t.tick() is State.SKIPPED
    assert t.tick_until_result(max_ticks=3) is State.SKIPPED
    assert t.tick_once() is State.SKIPPED


def test_a_skipped_condition_fails_as_behaviortree_cpp_throws() -> None:
    body = '<IfThenElse><Cond name="c" _skipIf="true"/><Cond name="a"/></IfThenElse>'
    with pytest.raises(RuntimeError):
        BtcppRun(_xml(body), {"c": "S", "a": "S"}).tick()
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mine = BtcapRun(_xml(body), {"c": "S", "a": "S"})
        assert mine.tick()[0] == "E"
    assert "its condition was skipped" in str(mine.tree.root.error)
    assert "skipped_condition" in DIFFERENCES


@pytest.mark.parametrize("once", [False, True], ids=["tickExactlyOnce", "tickOnce"])
def test_random_trees_with_skip_if_and_while_agree_with_behaviortree_cpp(once: bool) -> None:
    ticks = ended = 0
    stopped: set[str] = set()
    with capture_logs(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for seed in range(250):
            rng = random.Random(seed)
            root = script_oracle.with_conditions(random_tree(rng, 3 + seed % 2), rng, True)
            out = script_oracle.compare_conditions(root, once=once)
            assert out.mismatch is None, f"seed {seed}: {out.mismatch}"
            ticks += out.ticks
            ended += out.error is None
            stopped.add(out.error or "")
    assert ticks > 1200
    assert ended > 150
    documented = {
        "conditions_checked_when_idle",
        "refused by BehaviorTree.CPP",
        "",
        WAKES_FOREVER,
    }
    assert stopped <= documented | set(DIFFERENCES)
