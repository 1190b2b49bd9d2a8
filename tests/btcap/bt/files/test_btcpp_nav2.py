"""A dry run of the Nav2-shaped navigator of ``examples/nav2/``: Nav2's control nodes
decide as Nav2's (:mod:`btcap.bt.nav2_nodes`), the others stood in for say so; and what
a file written for BehaviorTree.CPP v3 or with its defaults is told."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import anyio
import pytest

from btcap import (
    Node,
    State,
    Subtree,
    Tree,
    TreeFileError,
    default_registry,
    load_tree,
    loads_tree,
)
from btcap.actors import ManualClock
from btcap.bt.files import TreeFileWarning

NAV2 = Path(__file__).resolve().parents[4] / "examples" / "nav2"
RECOVERIES = ("ClearingActions", "Spin", "Wait", "BackUp")


async def _dry_run(script: dict[str, Any]) -> tuple[State, Tree, list[str]]:
    """Run dry_run.xml to a result; the names of the navigator's nodes that ran."""
    clock = ManualClock()
    tree = load_tree(
        NAV2 / "dry_run.xml",
        default_registry(plugins=False),
        clock=clock,
        stub_missing=True,
        models=[NAV2 / "nav2_tree_nodes.xml"],
        stub_script=script,
    )
    sub = tree.find("Sequence/NavigateWithReplanning")
    assert isinstance(sub, Subtree)
    changed: list[str] = []

    def ran(node: Node, old: State, new: State) -> None:
        if new in (State.RUNNING, State.SUCCEEDED, State.FAILED):
            changed.append(node.name)

    stop = sub.inner.observe(ran)
    with anyio.fail_after(10):
        async with clock.autojump():
            state = await tree.run(10.0)
    stop()
    await tree.shutdown()
    return state, sub.inner, changed


async def test_no_recovery_runs_after_navigation_succeeded() -> None:
    """The bug of a Sequence standing in for RecoveryNode: every recovery ran."""
    state, _, changed = await _dry_run({"types": {"FollowPath": ["RUNNING", "SUCCESS"]}})
    assert state is State.SUCCEEDED
    assert not set(RECOVERIES) & set(changed)
    assert "ClearLocalCostmap-Context" not in changed


async def test_a_failing_navigation_recovers_in_turn_then_gives_up() -> None:
    script = {"types": {"FollowPath": "FAILURE", "GoalUpdated": "FAILURE"}}
    state, _, changed = await _dry_run(script)
    assert state is State.FAILED
    assert set(RECOVERIES) <= set(changed)  # the RoundRobin took each in turn


def test_a_control_stood_in_for_says_so() -> None:
    text = """<root BTCPP_format="4">
      <BehaviorTree ID="M"><PersistentSequence><AlwaysSuccess/></PersistentSequence></BehaviorTree>
      <TreeNodesModel><Control ID="PersistentSequence"/></TreeNodesModel>
    </root>"""
    with pytest.warns(TreeFileWarning, match="PersistentSequence is Nav2's.*stand-in ticks"):
        tree = loads_tree(text, "xml", default_registry(plugins=False), stub_missing=True)
    assert isinstance(tree.root, Node)


def _problems(body: str) -> list[str]:
    text = f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>'
    try:
        loads_tree(text, "xml", default_registry(plugins=False), name="t.xml")
    except TreeFileError as exc:
        return exc.problems
    return []


def test_runonce_without_then_skip_loads_with_behaviortree_cpps_default() -> None:
    assert _problems("<RunOnce><AlwaysSuccess/></RunOnce>") == []


def test_v3_sequence_star_hints_at_v4_sequence_with_memory() -> None:
    problems = _problems("<SequenceStar><AlwaysSuccess/></SequenceStar>")
    assert "v4 calls it SequenceWithMemory" in problems[0]


def test_names_with_slashes_and_dots_load_with_underscores() -> None:
    """As MoveIt Pro's files name nodes ("Move/To.Pose"); btcap's paths use both."""
    text = (
        '<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence name="arm/move.to">'
        '<AlwaysSuccess name="a.b"/></Sequence></BehaviorTree></root>'
    )
    tree = loads_tree(text, "xml", default_registry(plugins=False))
    assert tree.find("arm_move_to/a_b").name == "a_b"
