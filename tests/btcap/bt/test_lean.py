"""What keeps nodes small and ticks cheap must not show: shared empties refuse writes,
State behaves as the Enum it is, and a reset reaches only the nodes that ran."""

from __future__ import annotations

import enum
import pickle
import sys

import msgspec
import pytest

from btcap import (
    AlwaysSuccess,
    Leaf,
    Parallel,
    Port,
    Sequence,
    State,
    Tree,
    TreeError,
)
from btcap._enum import FastEnumType
from btcap.bt.messages import NodeStatus


class Counting(Leaf):
    """Gives its scripted results in turn and counts its resets."""

    __slots__ = ("resets", "script", "ticks")

    def __init__(self, name: str, script: str) -> None:
        super().__init__(name)
        self.script = script
        self.ticks = 0
        self.resets = 0

    def on_tick(self) -> State:
        result = {"S": State.SUCCEEDED, "F": State.FAILED, "R": State.RUNNING}
        s = result[self.script[min(self.ticks, len(self.script) - 1)]]
        self.ticks += 1
        return s

    def on_reset(self) -> None:
        self.resets += 1
        self.ticks = 0


class WithOutput(Leaf):
    OUTPUTS = {"x": int}
    OPTIONS = {"k": Port(int, 1)}

    def on_tick(self) -> State:
        self.outputs["x"] = self.options["k"]
        return State.SUCCEEDED


def test_a_node_without_ports_refuses_writes_to_them() -> None:
    leaf = AlwaysSuccess("a")
    assert leaf.inputs == {}
    assert leaf.outputs == {}
    assert leaf.options == {}
    with pytest.raises(TreeError, match="no port or option 'x'"):
        leaf.outputs["x"] = 1
    with pytest.raises(TreeError, match="declares no ports"):
        leaf.inputs.update(x=1)
    with pytest.raises(TreeError, match="takes no children"):
        leaf.children.append(AlwaysSuccess("b"))
    assert AlwaysSuccess("c").outputs == {}
    assert leaf.children == []
    assert pickle.loads(pickle.dumps(leaf.outputs)) == {}


def test_nodes_with_ports_keep_their_own_values() -> None:
    a, b = WithOutput("a", k=1), WithOutput("b", k=2)
    tree = Tree(Sequence("root", children=[a, b]))
    tree.setup()
    assert tree.tick() is State.SUCCEEDED
    assert (a.outputs, b.outputs) == ({"x": 1}, {"x": 2})
    tree.reset()
    assert (a.outputs, b.outputs) == ({"x": None}, {"x": None})


def test_state_is_still_the_enum() -> None:
    assert isinstance(State, enum.EnumMeta)
    assert issubclass(State, enum.Enum)
    assert State.SUCCEEDED is State("succeeded") is State["SUCCEEDED"]
    assert len(list(State)) == len(State.__members__) == 11
    assert State.SUCCEEDED.value == "succeeded"
    assert State.SUCCEEDED.name == "SUCCEEDED"
    assert pickle.loads(pickle.dumps(State.PAUSED)) is State.PAUSED
    status = NodeStatus(State.FAILED, {"x": 1})
    assert msgspec.msgpack.decode(msgspec.msgpack.encode(status), type=NodeStatus) == status
    with pytest.raises(ValueError, match="not a valid State"):
        State("bogus")
    with pytest.raises(AttributeError):
        State.BOGUS  # noqa: B018
    with pytest.raises(AttributeError, match="cannot reassign"):
        State.IDLE = State.RUNNING  # type: ignore[misc]
    assert State._missing_("x") is None  # inherited from Enum: the full lookup


def test_the_documented_leaf_returns_the_states_themselves() -> None:
    import btcap

    assert btcap.SUCCEEDED is State.SUCCEEDED
    assert btcap.FAILED is State.FAILED
    assert btcap.RUNNING is State.RUNNING

    class Ready(btcap.Leaf):
        def on_tick(self) -> State:
            return btcap.SUCCEEDED

    assert btcap.Tree(Ready("ready")).tick() is State.SUCCEEDED


@pytest.mark.skipif(sys.version_info >= (3, 12), reason="the check exists where the toll does")
def test_a_fast_enum_refuses_members_that_need_binding() -> None:
    with pytest.raises(TypeError, match="reads differently from the class"):

        class Bad(enum.Enum, metaclass=FastEnumType):
            A = 1

            @classmethod
            def make(cls) -> Bad:
                return cls.A


def test_a_parallel_starting_over_resets_only_what_ran() -> None:
    # The Parallel succeeds once ``quick`` does; ``slow`` is halted mid-way, its Sequence
    # having ticked ``first`` (done) and ``second`` (running) but never ``third``.
    quick = Counting("quick", "S")
    first, second, third = Counting("first", "S"), Counting("second", "R"), Counting("third", "S")
    slow = Sequence("slow", children=[first, second, third])
    tree = Tree(Parallel("p", children=[quick, slow], success_threshold=1))
    tree.setup()
    assert tree.tick() is State.SUCCEEDED
    assert (slow.state, second.state, third.state) == (State.PAUSED, State.PAUSED, State.IDLE)
    assert tree.tick() is State.SUCCEEDED  # starting over: slow and what ran below it reset
    assert (first.resets, second.resets, third.resets, quick.resets) == (1, 1, 0, 0)
