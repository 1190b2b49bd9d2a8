"""Typed data: ports, options, inputs, wires (checked when built), flow and validation."""

from __future__ import annotations

from typing import Any, Optional

import pytest

from btcap import (
    AlwaysSuccess,
    Constant,
    Inverter,
    Leaf,
    Parallel,
    Port,
    ReactiveSequence,
    State,
    Tree,
    TreeError,
)
from btcap.bt.node import declared_ports
from btcap.bt.ports import NO_DEFAULT, assignable, check_value, normalize_ports, type_name


class Sink(Leaf):
    """Remembers every ``x`` it saw."""

    INPUTS = {"x": int, "label": Port(str, "none"), "maybe": Optional[float]}

    def __init__(self, name: str = "sink", **kw: Any) -> None:
        super().__init__(name, **kw)
        self.seen: list[Any] = []

    def on_tick(self) -> State:
        self.seen.append(self.inputs["x"])
        return State.SUCCEEDED


class Source(Leaf):
    """Outputs its tick count (an int) and a float."""

    OUTPUTS = {"n": int, "f": float, "text": str, "anything": Any}

    def __init__(self, name: str = "src") -> None:
        super().__init__(name)
        self.count = 0

    def on_tick(self) -> State:
        self.count += 1
        self.outputs["n"] = self.count
        self.outputs["f"] = self.count / 2
        return State.SUCCEEDED


class Configured(Leaf):
    OPTIONS = {
        "speed": float,
        "mode": Port(str, "safe", "how careful"),
        "limit": Port(int | None),
        "tags": Port(list[str], []),
    }

    def on_tick(self) -> State:
        return State.SUCCEEDED


# -- ports ----------------------------------------------------------------------------


def test_port_required_and_defaults() -> None:
    assert Port(int).required
    assert Port(int).default is NO_DEFAULT
    assert Port(int).default_value() is None
    assert not Port(int, 3).required
    assert Port(int, 3).default_value() == 3
    assert not Port(int | None).required
    assert not Port(Optional[int]).required
    assert Port(Any).required
    assert repr(NO_DEFAULT) == "NO_DEFAULT"


def test_class_ports_are_normalized() -> None:
    assert Sink.INPUTS["x"] == Port(int)
    assert Sink.INPUTS["label"] == Port(str, "none")
    assert Configured.OPTIONS["mode"].description == "how careful"
    assert declared_ports(Sink()) == {"inputs": Sink.INPUTS, "outputs": {}, "options": {}}


@pytest.mark.parametrize("spec", [{"not valid": int}, {1: int}, {"a-b": int}])
def test_port_names_must_be_identifiers(spec: dict[Any, Any]) -> None:
    with pytest.raises(TypeError, match="is not an identifier"):
        normalize_ports(spec, "where")


def test_port_spec_must_be_a_dict() -> None:
    with pytest.raises(TypeError, match="expected a dict"):
        normalize_ports([int], "where")
    assert normalize_ports(None, "where") == {}


@pytest.mark.parametrize(
    ("src", "dst", "ok"),
    [
        (int, int, True),
        (int, float, True),
        (float, int, False),
        (bool, int, True),
        (str, int, False),
        (int, Any, True),
        (Any, int, True),
        (int, object, True),
        (int, int | None, True),
        (int | None, int, False),
        (int | None, float | None, True),
        (int | str, int | str | None, True),
        (list[int], list[int], True),
        (list[int], list[float], True),
        (list[str], list[int], False),
        (list[int], list, True),
        (list, list[int], False),
        (dict[str, int], dict[str, float], True),
        (dict[str, int], dict[int, int], False),
        (tuple[int, int], tuple[float, float], True),
        (tuple[int, int], tuple[int], False),
        (list[int], tuple[int], False),
    ],
)
def test_assignable(src: Any, dst: Any, ok: bool) -> None:
    assert assignable(src, dst) is ok


def test_type_names() -> None:
    assert type_name(int) == "int"
    assert type_name(Any) == "Any"
    assert type_name(list[int]) == "list[int]"
    assert type_name(Optional[int]) == "Optional[int]"
    assert type_name(int | None) == "int | None"


def test_check_value_converts_or_raises() -> None:
    assert check_value([1, 2], tuple[int, int], "w") == (1, 2)
    assert check_value(1, float, "w") == 1.0
    assert check_value("anything", Any, "w") == "anything"
    with pytest.raises(TreeError, match=r"^w: expected int, got str 'x'"):
        check_value("x", int, "w")
    with pytest.raises(TreeError, match="expected list\\[int\\]"):
        check_value([1, "a"], list[int], "w")


# -- options ----------------------------------------------------------------------------


def test_options_are_checked_and_defaulted() -> None:
    n = Configured("c", speed=2)
    assert n.options == {"speed": 2.0, "mode": "safe", "limit": None, "tags": []}
    assert isinstance(n.options["speed"], float)


def test_unknown_option_names_node_option_and_the_expected_ones() -> None:
    with pytest.raises(TreeError) as err:
        Configured("c", speed=1.0, sped=2.0)
    assert str(err.value) == (
        "node 'c' (Configured): unknown option(s) sped; expected limit, mode, speed, tags"
    )
    with pytest.raises(TreeError, match="unknown option\\(s\\) x; expected none"):
        AlwaysSuccess("a", x=1)


def test_missing_required_option_names_node_option_and_type() -> None:
    with pytest.raises(TreeError) as err:
        Configured("c")
    assert str(err.value) == "node 'c' (Configured): option 'speed' (float) is required"


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"speed": "fast"}, "node 'c' option 'speed': expected float, got str 'fast'"),
        ({"speed": 1.0, "mode": 3}, "node 'c' option 'mode': expected str, got int 3"),
        ({"speed": 1.0, "limit": 1.5}, "node 'c' option 'limit': expected int | None"),
        ({"speed": 1.0, "tags": ["a", 1]}, "node 'c' option 'tags': expected list[str]"),
    ],
)
def test_wrong_option_type_names_node_option_and_type(
    options: dict[str, Any], message: str
) -> None:
    with pytest.raises(TreeError) as err:
        Configured("c", **options)
    assert str(err.value).startswith(message)


# -- inputs ----------------------------------------------------------------------------


def test_inputs_start_at_their_defaults() -> None:
    assert Sink().inputs == {"x": None, "label": "none", "maybe": None}


def test_set_input_is_type_checked() -> None:
    s = Sink(inputs={"x": 3})
    assert s.inputs["x"] == 3
    s.set_input("maybe", 2)
    assert s.inputs["maybe"] == 2.0
    with pytest.raises(TreeError, match="node 'sink' input 'x': expected int, got str 'three'"):
        s.set_input("x", "three")
    with pytest.raises(TreeError, match="node 'sink' input 'label': expected str"):
        Sink(inputs={"label": 5})
    with pytest.raises(TreeError) as err:
        s.set_input("y", 1)
    assert str(err.value) == "node 'sink' (Sink) has no input 'y'; inputs: x, label, maybe"


# -- wires ------------------------------------------------------------------------------


def make_tree(*nodes: Leaf) -> Tree:
    return Tree(ReactiveSequence("root", children=list(nodes)))


def test_values_flow_in_tick_order() -> None:
    src, sink = Source(), Sink()
    tree = make_tree(src, sink)
    tree.wire(src, "n", sink, "x")
    tree.wire("root/src", "f", "root/sink", "maybe")
    for _ in range(3):
        assert tree.tick() is State.SUCCEEDED
    assert sink.seen == [1, 2, 3]  # delivered within the same tick
    assert sink.inputs["maybe"] == 1.5


def test_a_consumer_before_its_producer_sees_the_previous_tick() -> None:
    sink, src = Sink(), Source()
    tree = make_tree(sink, src)
    tree.wire(src, "n", sink, "x")
    tree.tick()
    tree.tick()
    tree.tick()
    assert sink.seen == [None, 1, 2]


def test_constant_delivers_in_the_same_tick() -> None:
    k, sink = Constant("k", value=42, type=int), Sink()
    tree = make_tree(k, sink)
    tree.wire("root/k", "value", "root/sink", "x")
    tree.tick()
    assert sink.seen == [42]


def test_wire_to_unknown_ports() -> None:
    tree = make_tree(Source(), Sink())
    with pytest.raises(TreeError) as err:
        tree.wire("root/src", "m", "root/sink", "x")
    assert str(err.value) == (
        "wire root/src.m -> root/sink.x: 'root/src' has no output 'm' "
        "(outputs: n, f, text, anything)"
    )
    with pytest.raises(TreeError) as err:
        tree.wire("root/src", "n", "root/sink", "y")
    assert str(err.value) == (
        "wire root/src.n -> root/sink.y: 'root/sink' has no input 'y' (inputs: x, label, maybe)"
    )
    with pytest.raises(TreeError, match="has no output 'x' \\(outputs: none\\)"):
        tree.wire("root/sink", "x", "root/src", "n")


def test_wire_type_mismatch_names_both_ends_and_types() -> None:
    tree = make_tree(Source(), Sink())
    with pytest.raises(TreeError) as err:
        tree.wire("root/src", "f", "root/sink", "x")
    assert str(err.value) == (
        "wire root/src.f -> root/sink.x: output is float but the input expects int"
    )
    with pytest.raises(TreeError, match="output is str but the input expects Optional\\[float\\]"):
        tree.wire("root/src", "text", "root/sink", "maybe")


def test_wire_int_into_float_and_any_into_int() -> None:
    src, sink = Source(), Sink()
    tree = make_tree(src, sink)
    tree.wire(src, "n", sink, "maybe")
    tree.wire(src, "anything", sink, "x")
    assert len(tree.wires) == 2
    assert repr(tree.wires[0]) == "Wire(root/src.n -> root/sink.maybe)"


def test_an_input_takes_only_one_wire() -> None:
    a, b, sink = Source("a"), Source("b"), Sink()
    tree = make_tree(a, b, sink)
    tree.wire(a, "n", sink, "x")
    with pytest.raises(TreeError, match=r"input root/sink\.x is already wired"):
        tree.wire(b, "n", sink, "x")
    tree.wire(a, "n", sink, "maybe")  # one output may feed several inputs


def test_wire_needs_nodes_of_this_tree() -> None:
    tree = make_tree(Source(), Sink())
    stranger = Sink("stranger")
    with pytest.raises(TreeError, match="node 'stranger' is not part of tree 'root'"):
        tree.wire("root/src", "n", stranger, "x")
    with pytest.raises(TreeError, match="no node 'root/nobody'"):
        tree.wire("root/src", "n", "root/nobody", "x")


def test_unwire_stops_the_flow() -> None:
    src, sink = Source(), Sink()
    tree = make_tree(src, sink)
    w = tree.wire(src, "n", sink, "x")
    tree.tick()
    tree.unwire(w)
    assert tree.wires == []
    tree.tick()
    assert sink.seen == [1, 1]  # the last value stays, no longer updated
    tree.wire(src, "n", sink, "x")  # the input is free again
    tree.tick()
    assert sink.seen == [1, 1, 3]


def test_unwire_keeps_the_other_wires() -> None:
    src, sink = Source(), Sink()
    tree = make_tree(src, sink)
    w1 = tree.wire(src, "n", sink, "x")
    tree.wire(src, "f", sink, "maybe")
    tree.tick()
    tree.unwire(w1)
    tree.tick()
    assert sink.seen == [1, 1]
    assert sink.inputs["maybe"] == 1.0


def test_wire_within_nested_structure() -> None:
    src, sink = Source(), Sink()
    tree = Tree(
        Parallel(
            "root", children=[ReactiveSequence("a", children=[src]), Inverter("b", children=[sink])]
        )
    )
    tree.wire("root/a/src", "n", "root/b/sink", "x")
    assert tree.tick() is State.FAILED
    assert sink.seen == [1]


# -- validation ---------------------------------------------------------------------------


def test_validate_catches_missing_required_inputs() -> None:
    src, sink = Source(), Sink()
    tree = make_tree(src, sink)
    with pytest.raises(TreeError) as err:
        tree.validate()
    assert str(err.value) == "node 'root/sink': input 'x' needs a value or a wire"
    with pytest.raises(TreeError, match="needs a value or a wire"):
        tree.tick()  # ticking validates first
    tree.wire(src, "n", sink, "x")
    tree.validate()
    sink.set_input("x", 1)
    tree.validate()
    assert tree.tick() is State.SUCCEEDED


def test_validate_accepts_a_constant_value() -> None:
    make_tree(Sink(inputs={"x": 0})).validate()


def test_validate_checks_child_counts() -> None:
    tree = Tree(ReactiveSequence("root", children=[Inverter("inv")]))
    with pytest.raises(TreeError) as err:
        tree.validate()
    assert str(err.value) == "node 'root/inv' (Inverter) has 0 children; expected 1 to 1"


def test_validate_accepts_inputs_provided_from_outside() -> None:
    sink = Sink()
    tree = make_tree(sink)
    tree.validate(provided=[(sink, "x")])
    with pytest.raises(TreeError, match="input 'x' needs a value or a wire"):
        tree.validate(provided=[(Sink(), "x")])
