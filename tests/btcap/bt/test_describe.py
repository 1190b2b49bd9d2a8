"""One description of a node for files and pictures: what differs from its defaults."""

from __future__ import annotations

from typing import Any, ClassVar

from btcap import (
    Compare,
    Constant,
    Leaf,
    Log,
    Port,
    ReactiveSequence,
    Retry,
    State,
    Subtree,
    Tree,
    dump_tree,
)
from btcap.bt.describe import describe, same, wire_sources


class Opaque:
    """A value that cannot be compared: ``==`` raises, as numpy arrays' truth does."""

    def __eq__(self, other: object) -> bool:
        raise ValueError("ambiguous")

    __hash__ = object.__hash__


class Holder(Leaf):
    INPUTS: ClassVar[Any] = {"x": Port(Any, None), "n": Port(float, 1.0)}

    def on_tick(self) -> State:
        return State.SUCCEEDED


def test_same_needs_equal_values_of_one_type() -> None:
    assert same([1, 2], [1, 2])
    assert not same(1, 1.0)
    assert not same(True, 1)
    assert not same(Opaque(), None)


def test_options_required_or_changed_in_declaration_order() -> None:
    log = Log("say", level="debug", message="hi")
    tree = Tree(log)
    assert describe(log, wire_sources(tree)).options == {"message": "hi", "level": "debug"}
    quiet = Log("quiet", message="hi")  # level left at its default
    assert describe(quiet, {}).options == {"message": "hi"}
    assert describe(Retry("r", retries=1, children=[quiet]), {}).options == {}


def test_inputs_are_constants_wires_or_fed_from_outside() -> None:
    src = Constant("src", value=2.0, type=float)
    cmp = Compare("cmp", op="<", inputs={"b": 10.0})
    holder = Holder("h", inputs={"x": Opaque(), "n": 1.0})
    tree = Tree(ReactiveSequence("root", children=[src, cmp, holder]))
    tree.wire(src, "value", cmp, "a")
    wires = wire_sources(tree)
    assert wires == {(id(cmp), "a"): "root/src.value"}

    about = describe(cmp, wires)
    assert about.wired == {"a": "root/src.value"}
    assert about.inputs == {"b": 10.0}
    assert describe(cmp, wires, fed=[(id(cmp), "b")]).inputs == {}

    held = describe(holder, wires)
    assert list(held.inputs) == ["x"]  # incomparable counts as set; n equals its default
    assert held.wired == {}


def test_a_subtree_file_leaves_out_values_fed_through_public_inputs() -> None:
    inner = Tree(Compare("cmp", op="<", inputs={"b": 10.0}), name="near")
    sub = Subtree(inner, "check", public_inputs={"distance": "cmp.a"})
    tree = Tree(ReactiveSequence("root", children=[sub]))
    sub.set_input("distance", 3.0)
    tree.tick()  # copies the public input into the inner node
    assert inner.root.inputs["a"] == 3.0
    spec = dump_tree(tree).subtrees["near"]
    assert spec.root is not None
    assert spec.root.inputs == {"b": 10.0}
    assert dump_tree(tree).root.children[0].inputs == {"distance": 3.0}
