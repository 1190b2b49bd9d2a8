"""BehaviorTree.CPP v4 XML: mapping, subtrees with remapping, blackboard wiring, errors.

The trees here are written for these tests; each error test asserts the file, the line
and the element or port the message names.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from btcap import (
    Leaf,
    NodeRegistry,
    Port,
    State,
    Subtree,
    Tree,
    TreeFileError,
    default_registry,
    dumps_tree,
    load_implementation,
    load_interfaces,
    load_tree,
    loads_tree,
    render_text,
)
from btcap.actors import ManualClock

ROOT = Path(__file__).resolve().parents[4]
EXAMPLES = ROOT / "examples"


class Move(Leaf):
    """Test node: a typed input and a typed output, and an option."""

    INPUTS = {"goal": tuple[float, float]}
    OUTPUTS = {"distance": float}
    OPTIONS = {"speed": Port(float, 1.0)}

    def on_tick(self) -> State:
        x, y = self.inputs["goal"]
        self.outputs["distance"] = abs(x) + abs(y)
        return State.SUCCEEDED


class Check(Leaf):
    """Test node: succeeds when its float input is at least ``minimum``."""

    INPUTS = {"value": float}
    OPTIONS = {"minimum": Port(float, 0.0)}

    def on_tick(self) -> State:
        return State.SUCCEEDED if self.inputs["value"] >= self.options["minimum"] else State.FAILED


class Flaky(Leaf):
    """Test node: fails on its first ``fails`` ticks, then succeeds; counts every tick."""

    OPTIONS = {"fails": Port(int, 1)}
    OUTPUTS = {"count": int}

    def on_tick(self) -> State:
        n = (self.outputs["count"] or 0) + 1
        self.outputs["count"] = n
        return State.FAILED if n <= self.options["fails"] else State.SUCCEEDED


class Pending(Leaf):
    """Test node: running for ``ticks`` ticks, then succeeded; counts every tick."""

    OPTIONS = {"ticks": Port(int, 1)}
    OUTPUTS = {"count": int}

    def on_tick(self) -> State:
        n = (self.outputs["count"] or 0) + 1
        self.outputs["count"] = n
        return State.SUCCEEDED if n > self.options["ticks"] else State.RUNNING


def _registry() -> NodeRegistry:
    reg = default_registry(plugins=False)
    for cls in (Move, Check, Pending, Flaky):
        reg.register(cls)
    return reg


def _xml(body: str, main: str | None = "Main") -> str:
    head = f' main_tree_to_execute="{main}"' if main else ""
    return f'<root BTCPP_format="4"{head}>\n{textwrap.dedent(body).strip()}\n</root>\n'


def _load(text: str) -> Tree:
    return loads_tree(text, "xml", _registry(), name="t.xml")


def _types(tree: Tree) -> list[str]:
    return [type(n).__name__ for n in tree.nodes()]


# -- standard nodes -------------------------------------------------------------------
MAPPED = [
    ("<Sequence><AlwaysSuccess/></Sequence>", "Sequence", {}),
    ("<AsyncSequence><AlwaysSuccess/></AsyncSequence>", "AsyncSequence", {}),
    ("<AsyncFallback><AlwaysSuccess/></AsyncFallback>", "AsyncFallback", {}),
    (
        "<SequenceWithMemory><AlwaysSuccess/></SequenceWithMemory>",
        "AsyncSequenceWithMemory",
        {},
    ),
    ("<ReactiveSequence><AlwaysSuccess/></ReactiveSequence>", "ReactiveSequence", {}),
    ("<Fallback><AlwaysSuccess/></Fallback>", "Fallback", {}),
    ("<ReactiveFallback><AlwaysSuccess/></ReactiveFallback>", "ReactiveFallback", {}),
    (
        '<Parallel success_count="1"><AlwaysSuccess/><AlwaysSuccess/></Parallel>',
        "Parallel",
        {"success_threshold": 1, "failure_threshold": 1},
    ),
    (
        '<Parallel failure_count="-1"><AlwaysSuccess/></Parallel>',
        "Parallel",
        {"success_threshold": -1, "failure_threshold": -1},
    ),
    ("<WhileDoElse><AlwaysSuccess/><AlwaysSuccess/></WhileDoElse>", "WhileDoElse", {}),
    ("<IfThenElse><AlwaysSuccess/><AlwaysSuccess/></IfThenElse>", "LatchedIfThenElse", {}),
    (
        '<ParallelAll max_failures="2"><AlwaysSuccess/><AlwaysFailure/></ParallelAll>',
        "ParallelAll",
        {"max_failures": 2},
    ),
    ("<Inverter><AlwaysSuccess/></Inverter>", "Inverter", {}),
    ("<ForceSuccess><AlwaysFailure/></ForceSuccess>", "ForceSuccess", {}),
    ("<ForceFailure><AlwaysSuccess/></ForceFailure>", "ForceFailure", {}),
    (
        "<KeepRunningUntilFailure><AlwaysSuccess/></KeepRunningUntilFailure>",
        "SuccessIsRunning",
        {},
    ),
    (
        '<RetryUntilSuccessful num_attempts="4"><AlwaysSuccess/></RetryUntilSuccessful>',
        "RepeatUntilSuccess",
        {"max_attempts": 4},
    ),
    (
        '<RetryUntilSuccessful num_attempts="-1"><AlwaysSuccess/></RetryUntilSuccessful>',
        "RepeatUntilSuccess",
        {"max_attempts": None},
    ),
    ('<Repeat num_cycles="3"><AlwaysSuccess/></Repeat>', "Repeat", {"times": 3}),
    ('<Timeout msec="1500"><AlwaysSuccess/></Timeout>', "Timeout", {"seconds": 1.5}),
    ('<Delay delay_msec="250"><AlwaysSuccess/></Delay>', "Delay", {"seconds": 0.25}),
    ('<RunOnce then_skip="false"><AlwaysSuccess/></RunOnce>', "RunOnce", {"then_skip": False}),
    ("<RunOnce><AlwaysSuccess/></RunOnce>", "RunOnce", {"then_skip": True}),
    ('<Sleep msec="20"/>', "Wait", {"seconds": 0.02}),
    ("<AlwaysFailure/>", "AlwaysFailure", {}),
]


@pytest.mark.parametrize(("element", "kind", "options"), MAPPED, ids=[m[1] for m in MAPPED])
def test_standard_nodes_map_to_btcap_nodes(
    element: str, kind: str, options: dict[str, Any]
) -> None:
    tree = _load(_xml(f'<BehaviorTree ID="Main">{element}</BehaviorTree>'))
    assert type(tree.root).__name__ == kind
    for key, value in options.items():
        assert tree.root.options[key] == value


def test_node_names_default_to_the_element_and_are_made_unique() -> None:
    tree = _load(
        _xml("""
        <BehaviorTree ID="Main">
          <Sequence name="main">
            <AlwaysSuccess/>
            <AlwaysSuccess/>
            <Action ID="AlwaysSuccess" name="ok"/>
            <AlwaysSuccess name="ok"/>
          </Sequence>
        </BehaviorTree>
        """)
    )
    assert [c.name for c in tree.root.children] == [
        "AlwaysSuccess",
        "AlwaysSuccess_2",
        "ok",
        "ok_2",
    ]


def test_sequence_resumes_at_the_running_child_and_reactive_sequence_does_not() -> None:
    """BehaviorTree.CPP's Sequence does not tick a succeeded child again while running."""
    body = """
    <BehaviorTree ID="Main">
      <{kind}>
        <Pending name="first" ticks="0"/>
        <Pending name="second" ticks="2"/>
      </{kind}>
    </BehaviorTree>
    """
    for kind, first_ticks in (("Sequence", 1), ("ReactiveSequence", 3)):
        tree = _load(_xml(body.format(kind=kind)))
        assert tree.tick_until_result() is State.SUCCEEDED
        assert tree.find(f"{kind}/first").outputs["count"] == first_ticks, kind


def test_sequence_with_memory_resumes_at_the_failed_child_and_sequence_starts_over() -> None:
    """BehaviorTree.CPP's SequenceWithMemory ticks the child that failed again next time;
    its Sequence starts over at the first child."""
    body = """
    <BehaviorTree ID="Main">
      <{kind}>
        <Pending name="first" ticks="0"/>
        <Flaky name="flaky" fails="1"/>
      </{kind}>
    </BehaviorTree>
    """
    for kind, first_ticks in (("SequenceWithMemory", 1), ("Sequence", 2)):
        tree = _load(_xml(body.format(kind=kind)))  # 4.8's SequenceWithMemory yields
        assert tree.tick_until_result() is State.FAILED
        assert tree.tick_until_result() is State.SUCCEEDED
        assert tree.find(f"{kind}/first").outputs["count"] == first_ticks, kind
        assert tree.find(f"{kind}/flaky").outputs["count"] == 2, kind


# -- a reference interpreter for synchronous trees --------------------------------------
_LEAVES = st.sampled_from(["AlwaysSuccess", "AlwaysFailure"])


def _trees(depth: int) -> st.SearchStrategy[Any]:
    if depth == 0:
        return _LEAVES
    sub = _trees(depth - 1)
    return st.one_of(
        _LEAVES,
        st.tuples(
            st.sampled_from(
                [
                    "Sequence",
                    "SequenceWithMemory",
                    "ReactiveSequence",
                    "Fallback",
                    "ReactiveFallback",
                ]
            ),
            st.lists(sub, min_size=1, max_size=4),
        ),
        st.tuples(
            st.sampled_from(["Inverter", "ForceSuccess", "ForceFailure"]), sub.map(lambda c: [c])
        ),
    )


def _to_xml(t: Any) -> str:
    if isinstance(t, str):
        return f"<{t}/>"
    kind, kids = t
    return f"<{kind}>{''.join(_to_xml(k) for k in kids)}</{kind}>"


def _expected(t: Any) -> bool:
    """BehaviorTree.CPP's result for a tree of synchronous leaves (True: SUCCESS)."""
    if isinstance(t, str):
        return bool(t == "AlwaysSuccess")
    kind, kids = t
    if "Sequence" in kind:
        return all(_expected(k) for k in kids)
    if kind.endswith("Fallback"):
        return any(_expected(k) for k in kids)
    if kind == "Inverter":
        return not _expected(kids[0])
    return bool(kind == "ForceSuccess")


@settings(max_examples=60, deadline=None)
@given(_trees(3))
def test_random_synchronous_trees_give_behaviortree_cpps_result(t: Any) -> None:
    tree = _load(_xml(f'<BehaviorTree ID="Main">{_to_xml(t)}</BehaviorTree>'))
    want = State.SUCCEEDED if _expected(t) else State.FAILED
    # SequenceWithMemory yields after an instant child in 4.8: a result, not in one tick
    assert tree.tick_until_result(max_ticks=100) is want
    again = loads_tree(dumps_tree(tree, registry=_registry()), "yaml", _registry())
    assert dumps_tree(again, registry=_registry()) == dumps_tree(tree, registry=_registry())


# -- blackboard wiring ----------------------------------------------------------------
def test_blackboard_entries_become_type_checked_wires() -> None:
    tree = _load(
        _xml("""
        <BehaviorTree ID="Main">
          <Sequence name="main">
            <SetBlackboard name="goal" output_key="target" value="3;-4"/>
            <Move name="move" goal="{target}" distance="{d}" speed="2.5"/>
            <Check name="far" value="{d}" minimum="6.5"/>
          </Sequence>
        </BehaviorTree>
        """)
    )
    assert [
        f"{w.source.path}.{w.source_port} -> {w.target.path}.{w.target_port}" for w in tree.wires
    ] == [
        "main/goal.value -> main/move.goal",
        "main/move.distance -> main/far.value",
    ]
    assert tree.find("main/goal").options["value"] == (3.0, -4.0)  # typed by its reader
    assert tree.find("main/move").options["speed"] == 2.5
    assert tree.tick() is State.SUCCEEDED
    assert tree.find("main/far").inputs["value"] == 7.0


def test_literal_inputs_are_converted_to_the_port_type() -> None:
    tree = _load(
        _xml("""
        <BehaviorTree ID="Main">
          <Sequence name="main">
            <Move name="move" goal="1.5; 2" distance="{d}"/>
            <Check name="ok" value="{d}" minimum="3"/>
          </Sequence>
        </BehaviorTree>
        """)
    )
    assert tree.find("main/move").inputs["goal"] == (1.5, 2.0)
    assert tree.tick() is State.SUCCEEDED


class Tally(Leaf):
    """Test node: typed list and boolean inputs, a float option."""

    INPUTS = {"ids": list[int], "loud": Port(bool, False)}
    OPTIONS = {"scale": Port(float, 1.0)}

    def on_tick(self) -> State:
        return State.SUCCEEDED


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.integers(-(10**9), 10**9), max_size=6),
    st.floats(allow_nan=False, allow_infinity=False),
    st.booleans(),
)
def test_literals_read_as_behaviortree_cpp_writes_them(
    ids: list[int], scale: float, loud: bool
) -> None:
    reg = _registry()
    reg.register(Tally)
    text = _xml(
        f'<BehaviorTree ID="Main"><Tally ids="{";".join(map(str, ids))}" scale="{scale!r}" '
        f'loud="{str(loud).lower()}"/></BehaviorTree>'
    )
    tree = loads_tree(text, "xml", reg)
    assert tree.root.inputs == {"ids": ids, "loud": loud}
    assert tree.root.options["scale"] == scale


# -- subtrees -------------------------------------------------------------------------
SUBTREES = _xml("""
<BehaviorTree ID="Main">
  <Sequence name="main">
    <SetBlackboard name="home" output_key="home" value="1;1"/>
    <SubTree ID="Leg" name="out" goal="{home}" distance="{first}"/>
    <SubTree ID="Leg" name="back" goal="2;2" _autoremap="true"/>
    <SubTree ID="Report" _autoremap="true"/>
  </Sequence>
</BehaviorTree>
<BehaviorTree ID="Leg">
  <Move name="move" goal="{goal}" distance="{distance}"/>
</BehaviorTree>
<BehaviorTree ID="Report">
  <Check name="check" value="{distance}" minimum="4"/>
</BehaviorTree>
""")


def test_subtrees_remap_ports_by_attribute_literal_and_autoremap() -> None:
    tree = _load(SUBTREES)
    out, back, report = (tree.find(p) for p in ("main/out", "main/back", "main/Report"))
    assert isinstance(out, Subtree)
    assert isinstance(back, Subtree)
    assert set(out.input_ports) == {"goal"}
    assert set(out.output_ports) == {"distance"}
    assert back.inputs["goal"] == (2.0, 2.0)
    wires = {
        f"{w.source.path}.{w.source_port} -> {w.target.path}.{w.target_port}" for w in tree.wires
    }
    assert wires == {
        "main/home.value -> main/out.goal",
        "main/back.distance -> main/Report.distance",  # autoremapped on both sides
    }
    assert tree.tick() is State.SUCCEEDED
    assert out.outputs["distance"] == 2.0
    assert report.inputs["distance"] == 4.0


def test_nested_subtrees_pass_entries_through() -> None:
    tree = _load(
        _xml("""
        <BehaviorTree ID="Main">
          <Sequence name="main">
            <SubTree ID="Outer" target="5;0" result="{r}"/>
            <Check name="check" value="{r}" minimum="5"/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Outer">
          <SubTree ID="Inner" goal="{target}" distance="{result}"/>
        </BehaviorTree>
        <BehaviorTree ID="Inner">
          <Move goal="{goal}" distance="{distance}"/>
        </BehaviorTree>
        """)
    )
    assert tree.tick() is State.SUCCEEDED
    assert tree.find("main/check").inputs["value"] == 5.0


def test_xml_round_trips_through_yaml_and_show() -> None:
    tree = _load(SUBTREES)
    text = dumps_tree(tree, registry=_registry())
    again = loads_tree(text, "yaml", _registry())
    assert dumps_tree(again, registry=_registry()) == text
    assert render_text(again) == render_text(tree)


def test_example_patrol_has_the_shape_of_the_yaml_patrol() -> None:
    xml = load_tree(EXAMPLES / "trees" / "patrol.xml")
    yml = load_tree(EXAMPLES / "trees" / "patrol.yaml")
    assert [c.name for c in xml.root.children] == [c.name for c in yml.root.children]
    assert [type(c).__name__ for c in xml.root.children[2:4]] == ["Timeout", "Timeout"]
    assert xml.find("patrol/leg1").options == yml.find("patrol/leg1").options
    assert {n.inner.name for n in xml.nodes() if isinstance(n, Subtree)} == {"GoTo"}


async def test_example_patrol_ticks_to_success_in_virtual_time() -> None:
    import anyio

    clock = ManualClock()
    tree = load_tree(EXAMPLES / "trees" / "patrol.xml", clock=clock)
    with anyio.fail_after(10):
        async with clock.autojump():
            assert await tree.run(10.0) is State.SUCCEEDED
    assert tree.find("patrol/done").inputs["value"] == "arrived"
    assert clock.now() >= 1.0  # both legs drove for their 0.5 s
    await tree.shutdown()


def test_capability_bridges_and_an_implementation_with_an_xml_tree(tmp_path: Path) -> None:
    caps = EXAMPLES / "capabilities"
    interfaces = load_interfaces(caps / "interfaces.yaml")
    impl = tmp_path / "greet.yaml"
    (tmp_path / "greet_impl.xml").write_bytes((caps / "greet_impl.xml").read_bytes())
    impl.write_text(
        "btcap_implementation: 1\nname: greet-xml\ninterface: Greet\ntree: greet_impl.xml\n"
    )
    made = load_implementation(impl, interfaces)
    tree = made.build()
    assert isinstance(tree, Tree)
    assert [type(n).__name__ for n in tree.nodes()] == [
        "Sequence",
        "GreetInputs",
        "Log",
        "GreetOutputs",
    ]


# -- errors ---------------------------------------------------------------------------
ERRORS = [
    ('<root BTCPP_format="3"/>', 1, 'BTCPP_format="3": BehaviorTree.CPP 3.x files name nodes'),
    ('<root BTCPP_format="5"/>', 1, "BTCPP_format='5'; btcap reads BehaviorTree.CPP format 4"),
    ('<root BTCPP_format="4">\n<BehaviorTree ID="Main">\n<Sequence>\n</root>', 4, "malformed XML"),
    (
        '<!DOCTYPE r [<!ENTITY a "aaaa"><!ENTITY b "&a;&a;&a;">]>\n<root BTCPP_format="4"/>',
        1,
        "DOCTYPE or entity declaration",
    ),
    (
        _xml(
            '<BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>\n'
            '<BehaviorTree ID="B"><AlwaysSuccess/></BehaviorTree>',
            None,
        ),
        1,
        "main_tree_to_execute missing and 2 BehaviorTrees (A, B)",
    ),
    (_xml('<include path="other.xml"/>'), 2, "a tree read from text has no directory"),
    (_xml('<include ros_pkg="nav2_bt" path="a.xml"/>'), 2, "btcap does not look up ROS packages"),
    (
        _xml('<BehaviorTree ID="Main">\n<Sequence>\n<Wiggle/>\n</Sequence>\n</BehaviorTree>'),
        4,
        "<Wiggle>: unknown node type 'Wiggle' (1 element, line 4): register it (--load MODULE)",
    ),
    (
        _xml('<BehaviorTree ID="Main">\n<Script code="x:=1;"/>\n</BehaviorTree>'),
        3,
        "<Script> attribute 'code': column 5: unexpected trailing separator",
    ),
    (
        _xml('<BehaviorTree ID="Main">\n<Timeout><AlwaysSuccess/></Timeout>\n</BehaviorTree>'),
        3,
        "<Timeout> needs attribute 'msec'",
    ),
    (  # BehaviorTree.CPP starts no timer for 0: the child runs as long as it likes
        _xml(
            '<BehaviorTree ID="Main">\n<Timeout msec="0"><AlwaysSuccess/></Timeout>'
            "\n</BehaviorTree>"
        ),
        3,
        "<Timeout> attribute 'msec': msec=0 is no timeout in BehaviorTree.CPP",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Repeat num_cycles="0"><AlwaysSuccess/></Repeat>'
            "\n</BehaviorTree>"
        ),
        3,
        "<Repeat> attribute 'num_cycles': expected a count >= 1 or -1",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Parallel success_count="{n}"><AlwaysSuccess/></Parallel>'
            "\n</BehaviorTree>"
        ),
        3,
        "btcap takes this as a fixed option, not from the blackboard",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Inverter colour="red"><AlwaysSuccess/></Inverter>'
            "\n</BehaviorTree>"
        ),
        3,
        "<Inverter> has no attribute 'colour'",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Sequence>\n<Move goal="1;2" distance="{d}"/>\n'
            '<Flaky count="{d}"/>\n</Sequence>\n</BehaviorTree>'
        ),
        5,
        "{d} is written as int here and as float at line 4; an entry has one type",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Sequence>\n<Move goal="1;2" distance="{d}"/>\n'
            '<Flaky count="{d}"/>\n<Move goal="1;2" distance="{d}"/>\n</Sequence>\n'
            "</BehaviorTree>"
        ),
        5,
        "{d} is written as int here and as float at line 4",
    ),
    (
        _xml('<BehaviorTree ID="Main">\n<Move goal="{@g s}"/>\n</BehaviorTree>'),
        3,
        "blackboard names must be identifiers",
    ),
    (
        _xml('<BehaviorTree ID="Main">\n<Move goal="1;2" speed="{s}"/>\n</BehaviorTree>'),
        3,
        "Move's 'speed' is an option, set once when the tree is built",
    ),
    (
        _xml('<BehaviorTree ID="Main">\n<Move goal="1;2" gaol="3"/>\n</BehaviorTree>'),
        3,
        "Move has no port 'gaol' (inputs: goal; outputs: distance; options: speed)",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Sequence>\n<Move goal="a;b"/>\n</Sequence>\n</BehaviorTree>'
        ),
        4,
        "node 'Sequence/Move' input 'goal': expected tuple[float, float]",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<Sequence>\n<Move goal="1;2" distance="{d}"/>\n'
            '<Move name="m2" goal="{d}"/>\n</Sequence>\n</BehaviorTree>'
        ),
        5,
        "output is float but the input expects tuple[float, float]",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<SubTree ID="Nope"/>\n</BehaviorTree>\n'
            '<BehaviorTree ID="Noop"><AlwaysSuccess/></BehaviorTree>'
        ),
        3,
        "no <BehaviorTree ID='Nope'> (did you mean Noop?)",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<SubTree ID="Loop"/>\n</BehaviorTree>\n'
            '<BehaviorTree ID="Loop">\n<SubTree ID="Main"/>\n</BehaviorTree>'
        ),
        6,
        "the tree uses itself (Main -> Loop -> Main)",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main">\n<SubTree ID="Leg" gaol="{x}"/>\n</BehaviorTree>\n'
            '<BehaviorTree ID="Leg"><Move goal="{goal}"/></BehaviorTree>'
        ),
        3,
        "<SubTree ID='Leg'> port 'gaol': the tree neither reads it from outside (goal)",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main"><Move goal="1;2"/></BehaviorTree>\n<TreeNodesModel>\n'
            '<Action ID="Move">\n<input_port name="goal"/>\n<output_port name="dist"/>\n'
            "</Action>\n</TreeNodesModel>"
        ),
        6,
        "<TreeNodesModel> Move output_port 'dist': the btcap node type has no such output",
    ),
    (
        _xml(
            '<BehaviorTree ID="Main"><Grasp/></BehaviorTree>\n<TreeNodesModel>\n'
            '<Action ID="Grasp"/>\n</TreeNodesModel>'
        ),
        2,
        "unknown node type 'Grasp' (1 element, line 2); <TreeNodesModel> declares it (line 4): "
        "register it",
    ),
]


ERRORS.append(
    (
        _xml(
            '<BehaviorTree ID="Main"><SubTree ID="Leg" goal="1;2"/></BehaviorTree>\n'
            '<BehaviorTree ID="Leg"><Move goal="{goal}" distance="{d}"/></BehaviorTree>\n'
            '<TreeNodesModel>\n<SubTree ID="Leg">\n<input_port name="goal"/>\n'
            '<input_port name="d"/>\n</SubTree>\n</TreeNodesModel>'
        ),
        7,
        "SubTree 'Leg' input_port 'd': the tree does not read {d} from outside (it reads: goal)",
    )
)


@pytest.mark.parametrize(("text", "line", "message"), ERRORS, ids=[e[2][:40] for e in ERRORS])
def test_errors_name_the_file_line_and_element(text: str, line: int, message: str) -> None:
    with pytest.raises(TreeFileError) as info:
        _load(text)
    problems = info.value.problems
    assert all(p.startswith("t.xml: ") for p in problems), problems
    assert any(p.startswith(f"t.xml: line {line}: ") and message in p for p in problems), problems


def test_every_problem_of_a_file_is_reported_at_once() -> None:
    text = _xml(
        '<BehaviorTree ID="Main">\n<Sequence>\n<Wiggle/>\n<Switch3/>\n<Move goal="1;2" gaol="3"/>\n'
        "</Sequence>\n</BehaviorTree>"
    )
    with pytest.raises(TreeFileError) as info:
        _load(text)
    lines = [p.split(":")[1].strip() for p in info.value.problems]
    assert lines == ["line 4", "line 5", "line 6"]


def test_load_tree_reads_xml_files_and_names_them(tmp_path: Path) -> None:
    path = tmp_path / "bad.XML"
    path.write_text(_xml('<BehaviorTree ID="Main">\n<Wiggle/>\n</BehaviorTree>'))
    with pytest.raises(TreeFileError, match=rf"^{path}: line 3: <Wiggle>"):
        load_tree(path)


@pytest.mark.parametrize(("main", "what"), [("T0", "the tree"), ("Main", "subtree 'T0'")])
def test_subtrees_used_twice_per_level_are_refused_not_built_exponentially(
    main: str, what: str
) -> None:
    """Every <SubTree> use is a copy: 40 levels of two uses each would be 2**40 nodes,
    whether the main tree uses them or not (every BehaviorTree is checked)."""
    levels = [
        f'<BehaviorTree ID="T{i}"><Sequence><SubTree ID="T{i + 1}"/><SubTree ID="T{i + 1}"/>'
        "</Sequence></BehaviorTree>"
        for i in range(40)
    ]
    last = '<BehaviorTree ID="T40"><AlwaysSuccess/></BehaviorTree>'
    small = '<BehaviorTree ID="Main"><AlwaysSuccess/></BehaviorTree>'
    text = _xml("\n".join([small, *levels, last]), main)
    with pytest.raises(TreeFileError, match=rf"^t.xml: {what} expands to {2**42 - 3} nodes"):
        _load(text)


def test_elements_nested_without_bound_are_refused_naming_the_line() -> None:
    depth = 5000
    body = "<Inverter>\n" * depth + "<AlwaysSuccess/>" + "</Inverter>" * depth
    text = _xml(f'<BehaviorTree ID="Main">\n{body}\n</BehaviorTree>')
    with pytest.raises(TreeFileError, match=r"^t.xml: line 201: <Inverter> is nested 201"):
        _load(text)


def test_a_deep_tree_within_the_bound_loads_and_ticks() -> None:
    depth = 190
    body = "<Inverter>" * depth + "<AlwaysSuccess/>" + "</Inverter>" * depth
    tree = _load(_xml(f'<BehaviorTree ID="Main">{body}</BehaviorTree>'))
    assert tree.tick() is State.SUCCEEDED


def test_subtrees_nested_without_bound_are_refused_naming_the_line() -> None:
    """Each BehaviorTree is shallow, but a chain of 1000 SubTrees nests 2000 nodes deep."""
    chain = [
        f'<BehaviorTree ID="T{i}"><Inverter><SubTree ID="T{i + 1}"/></Inverter></BehaviorTree>'
        for i in range(1000)
    ]
    text = _xml(
        "\n".join([*chain, '<BehaviorTree ID="T1000"><AlwaysSuccess/></BehaviorTree>']), "T0"
    )
    with pytest.raises(
        TreeFileError, match=r"^t.xml: line 102: <SubTree ID='T101'> nests the tree 202 nodes deep"
    ):
        _load(text)


def test_run_once_runs_its_child_once_even_under_a_repeat() -> None:
    """BehaviorTree.CPP's RunOnce keeps its first result forever; a Repeat resetting it
    between cycles must not run the child again."""
    ticked: list[str] = []

    class Once(Leaf):
        def on_tick(self) -> State:
            ticked.append(self.name)
            return State.SUCCEEDED

    reg = _registry()
    reg.register(Once)
    body = '<Repeat num_cycles="3"><RunOnce then_skip="false"><Once/></RunOnce></Repeat>'
    tree = loads_tree(_xml(f'<BehaviorTree ID="Main">{body}</BehaviorTree>'), "xml", reg)
    assert [tree.tick() for _ in range(3)][-1] is State.SUCCEEDED
    assert ticked == ["Once"]
