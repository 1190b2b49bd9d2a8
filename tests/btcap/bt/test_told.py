"""A node's first error is told by default (a NodeErrorWarning), once per node of a tree,
at the line that raised; the standard filters quieten it or make it raise."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings

import anyio
import pytest

from btcap import (
    FAILED,
    Action,
    Fallback,
    Leaf,
    Log,
    NodeErrorWarning,
    Sequence,
    State,
    Tree,
)


class Gripper(Leaf):
    """Raises on every tick: a bug in a user's node."""

    def on_tick(self) -> State:
        raise ValueError("gripper offline")


def _fallback() -> tuple[Tree, Gripper]:
    grip = Gripper("grip")
    return Tree(Fallback("try", children=[grip, Log("give_up", message="skipped")])), grip


def test_the_first_error_of_a_node_is_a_warning_at_the_line_that_raised() -> None:
    tree, grip = _fallback()
    with pytest.warns(NodeErrorWarning) as said:
        assert tree.tick() is State.SUCCEEDED  # the Fallback hides it from the result
    [w] = said
    assert str(w.message).startswith(
        "node 'try/grip' (Gripper) raised ValueError in tick: gripper offline; it is in ERROR"
    )
    assert w.filename == __file__
    assert w.lineno == Gripper.on_tick.__code__.co_firstlineno + 1
    assert grip.state is State.ERROR


def test_later_errors_of_the_same_node_are_not_told_again() -> None:
    tree, _ = _fallback()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        for _ in range(5):
            tree.reset()
            tree.tick()
    assert [w.category for w in said] == [NodeErrorWarning]


async def test_an_async_action_is_told_with_the_line_in_its_function() -> None:
    async def dock() -> None:
        raise RuntimeError("dock busy")

    with anyio.fail_after(10):
        tree = Tree(Sequence("s", children=[Action(dock, "dock")]))
        with pytest.warns(NodeErrorWarning, match="node 's/dock' \\(Action\\) raised Runtime") as w:
            assert await tree.run(rate_hz=1000) is State.FAILED
        await tree.shutdown()
    assert [x.lineno for x in w] == [dock.__code__.co_firstlineno + 1]


def test_an_error_filter_raises_it_out_of_the_tick_unwrapped() -> None:
    tree, grip = _fallback()
    with warnings.catch_warnings():
        warnings.simplefilter("error", NodeErrorWarning)
        with pytest.raises(NodeErrorWarning, match="node 'try/grip'"):
            tree.tick()
    assert grip.state is State.ERROR
    assert tree.root.state is not State.ERROR  # the Fallback did not wrap it in its own


def test_an_ignore_filter_quietens_it() -> None:
    tree, _ = _fallback()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=NodeErrorWarning)
        assert tree.tick() is State.SUCCEEDED
    assert said == []


def test_a_node_that_fails_on_purpose_is_no_warning() -> None:
    class Closed(Leaf):
        def on_tick(self) -> State:
            return FAILED

    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        assert Tree(Closed("door")).tick() is State.FAILED
    assert said == []


def test_a_program_that_configured_nothing_sees_it_once_on_stderr() -> None:
    """Python's own defaults, as a user's script gets them (pytest's filters aside)."""
    code = textwrap.dedent(
        """\
        from btcap import Fallback, Leaf, Log, State, Tree

        class Gripper(Leaf):
            def on_tick(self) -> State:
                raise ValueError("gripper offline")

        tree = Tree(Fallback("try", children=[Gripper("grip"), Log("no", message="x")]))
        for _ in range(3):
            tree.reset()
            print(tree.tick().value)
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["succeeded"] * 3
    told = [line for line in done.stderr.splitlines() if "NodeErrorWarning" in line]
    assert len(told) == 1
    assert "<string>:5: NodeErrorWarning: node 'try/grip' (Gripper) raised ValueError" in told[0]
