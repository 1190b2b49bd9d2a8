"""Tree files: round trips in YAML and JSON, subtrees, and an error for every mistake.

Every error must name the file, the node path (or wire) and the field, so the error
tests assert all three, and that each reported line starts with the file path.
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path
from typing import Any

import pytest
from structlog.testing import capture_logs

import btcap
import btcap.bt.files
from btcap import (
    Action,
    Constant,
    Leaf,
    Log,
    NodeRegistry,
    Port,
    ReactiveSequence,
    Retry,
    State,
    Subtree,
    Tree,
    TreeError,
    TreeFile,
    TreeFileError,
    Wait,
    default_registry,
    dump_tree,
    dumps_tree,
    load_tree,
    loads_tree,
    render_text,
    save_tree,
    validate_file,
)
from btcap.actors import ManualClock
from btcap.bt.files import PublicSpec, file_info, read_tree_file

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "trees"


class Move(Leaf):
    """Test node: a required typed input and a typed output."""

    INPUTS = {"goal": tuple[float, float]}
    OUTPUTS = {"distance": float}
    OPTIONS = {"speed": Port(float, 1.0)}

    def on_tick(self) -> State:
        self.outputs["distance"] = abs(self.inputs["goal"][0]) + abs(self.inputs["goal"][1])
        return State.SUCCEEDED


@pytest.fixture
def registry() -> NodeRegistry:
    reg = default_registry(plugins=False)
    reg.register(Move)
    return reg


def write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip(), encoding="utf-8")
    return path


def shape(tree: Tree) -> dict[str, Any]:
    """What a round trip must keep: structure, options, inputs and wires."""
    return {
        "name": tree.name,
        "nodes": [
            (n.path, type(n).__name__, dict(n.options), dict(n.inputs), len(n.children))
            for n in tree.nodes()
        ],
        "wires": [repr(w) for w in tree.wires],
        "subtrees": {n.path: shape(n.inner) for n in tree.nodes() if isinstance(n, Subtree)},
    }


MISSION = """
btcap: 1
name: mission
description: Drive to a goal, retrying, and compare the distance.
root:
  type: ReactiveSequence
  name: root
  children:
    - {type: Constant, name: goal, options: {value: [3.0, -4.0], type: "tuple[float, float]"}}
    - type: Retry
      name: retry
      options: {retries: 3}
      children:
        - {type: Move, name: move, options: {speed: 2.5}}
    - {type: Subtree, name: check, options: {tree: near}}
wires:
  - {from: root/goal.value, to: root/retry/move.goal}
  - {from: root/retry/move.distance, to: root/check.distance}
subtrees:
  near:
    description: Succeeds when the distance is below a limit.
    root: {type: Compare, name: cmp, options: {op: "<"}, inputs: {b: 10.0}}
    public: {inputs: {distance: cmp.a}}
"""


# -- round trips ----------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".json"])
def test_round_trip_keeps_structure_options_inputs_and_wires(
    tmp_path: Path, registry: NodeRegistry, suffix: str
) -> None:
    first = load_tree(write(tmp_path / "mission.yaml", MISSION), registry)
    saved = save_tree(first, tmp_path / f"copy{suffix}", registry)
    second = load_tree(saved, registry)
    assert shape(second) == shape(first)
    assert dump_tree(second, registry) == dump_tree(first, registry)
    assert file_info(second).description == "Drive to a goal, retrying, and compare the distance."
    assert second.find("root/goal").options["type"] == tuple[float, float]
    assert second.find("root/retry/move").options["speed"] == 2.5
    # and a third generation writes byte-identical text
    fmt: Any = "json" if suffix == ".json" else "yaml"
    assert saved.read_text() == dumps_tree(second, fmt, registry)


def test_loaded_tree_runs_and_data_flows_through_the_subtree(registry: NodeRegistry) -> None:
    tree = loads_tree(MISSION, registry=registry)
    assert tree.tick() is State.SUCCEEDED
    check = tree.find("root/check")
    assert isinstance(check, Subtree)
    assert check.inputs["distance"] == 7.0
    assert tree.find("root/goal").outputs["value"] == (3.0, -4.0)


def test_tree_built_in_code_saves_and_loads_back(tmp_path: Path) -> None:
    root = ReactiveSequence(
        "root",
        children=[
            Constant("limits", value={"a": [1, 2]}, type=dict[str, list[int]] | None),
            Retry("retry", retries=2, children=[Wait("pause", seconds=0.25)]),
            Log("say", message="hello", level="debug"),
        ],
    )
    tree = Tree(root, name="built")
    tree.wire("root/limits", "value", "root/say", "value")
    for suffix in (".yaml", ".json"):
        loaded = load_tree(save_tree(tree, tmp_path / f"built{suffix}"))
        assert shape(loaded) == shape(tree)
        assert loaded.find("root/limits").options["type"] == dict[str, list[int]] | None


def test_defaults_are_left_out_and_wired_inputs_are_wires(registry: NodeRegistry) -> None:
    tree = loads_tree(MISSION, registry=registry)
    tree.tick()  # pulls wired values into inputs: they must still be written as wires
    text = dumps_tree(tree, "yaml", registry)
    spec = dump_tree(tree, registry)
    retry = spec.root.children[1]
    assert retry.options == {"retries": 3}
    assert retry.children[0].inputs == {}
    assert "failure_threshold" not in text
    assert [(w.source, w.target) for w in spec.wires] == [
        ("root/goal.value", "root/retry/move.goal"),
        ("root/retry/move.distance", "root/check.distance"),
    ]
    near = spec.subtrees["near"]
    assert near.public is not None
    assert near.public.inputs == {"distance": "cmp.a"}
    assert near.root is not None
    assert near.root.inputs == {"b": 10.0}  # the public input 'a' is not a constant


def test_the_outline_shows_exactly_the_settings_a_file_writes(registry: NodeRegistry) -> None:
    tree = loads_tree(MISSION, registry=registry)
    tree.tick()
    spec = dump_tree(tree, registry)
    lines = render_text(tree, states=False).splitlines()
    retry, move = spec.root.children[1], spec.root.children[1].children[0]
    assert "├── Retry 'retry'  retries=3" in lines
    assert retry.options == {"retries": 3}
    assert any(line.endswith("└── Move 'move'  speed=2.5") for line in lines)
    assert move.options == {"speed": 2.5}
    assert any(line.endswith("· in  goal <- root/goal.value") for line in lines)
    assert move.inputs == {}  # wired, so a wire and not a value, in the file as on screen
    assert any(line.endswith("· in  b = 10.0") for line in lines)


def test_every_name_of_the_files_package_resolves_and_matches_btcap() -> None:
    for name in btcap.bt.files.__all__:
        value = getattr(btcap.bt.files, name)
        if name in btcap.__all__:
            assert getattr(btcap, name) is value, name


def test_example_files_load_and_match(tmp_path: Path) -> None:
    yaml_tree = load_tree(EXAMPLES / "patrol.yaml")
    json_tree = load_tree(EXAMPLES / "patrol.json")
    assert dump_tree(yaml_tree) == dump_tree(json_tree)
    assert validate_file(EXAMPLES / "patrol.yaml") == []
    assert validate_file(EXAMPLES / "patrol.json") == []
    assert shape(load_tree(save_tree(yaml_tree, tmp_path / "p.json"))) == shape(yaml_tree)


async def test_example_patrol_runs_to_success() -> None:
    clock = ManualClock()
    tree = load_tree(EXAMPLES / "patrol.yaml", clock=clock)
    with capture_logs() as logs:
        state = tree.tick()
        for _ in range(50):
            if state is not State.RUNNING:
                break
            await clock.advance(0.1)
            state = tree.tick()
    assert state is State.SUCCEEDED
    goals = [e["value"] for e in logs if e["event"] == "moving to goal"]
    assert goals == [(1.0, 2.0), (4.0, 0.5)]  # each leg once: the Sequences resume
    assert clock.now() >= 1.0  # both 0.5 s drives were waited for


def test_the_module_docstring_example_is_a_valid_file() -> None:
    doc = btcap.bt.files.__doc__ or ""
    example = textwrap.dedent(doc.split("::\n\n", 1)[1].split("\n\n", 1)[0])
    tree = loads_tree(example)
    assert tree.tick() is State.SUCCEEDED
    assert tree.find("root/go").inputs["goal"] == [1.0, 2.0]


def test_read_tree_file_gives_the_schema_struct() -> None:
    spec = read_tree_file(EXAMPLES / "patrol.yaml")
    assert isinstance(spec, TreeFile)
    assert spec.btcap == 1
    assert spec.name == "patrol"
    assert set(spec.subtrees) == {"goto"}


def test_node_name_defaults_to_type_and_subtree_name_to_its_tree() -> None:
    tree = loads_tree(
        """
        btcap: 1
        root:
          type: ReactiveSequence
          children: [{type: AlwaysSuccess}, {type: Subtree, options: {tree: t}}]
        subtrees: {t: {root: {type: AlwaysFailure}}}
        """
    )
    assert [n.path for n in tree.nodes()] == [
        "ReactiveSequence",
        "ReactiveSequence/AlwaysSuccess",
        "ReactiveSequence/t",
    ]
    assert tree.name == "ReactiveSequence"


# -- subtrees from other files ----------------------------------------------------------
NAV = """
btcap: 1
name: nav
root:
  type: ReactiveSequence
  name: nav
  children:
    - {type: Move, name: move}
public:
  inputs: {goal: nav/move.goal}
  outputs: {distance: nav/move.distance}
"""


def test_subtree_from_another_file_and_saved_as_a_relative_ref(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    (tmp_path / "lib").mkdir()
    write(tmp_path / "lib" / "nav.yaml", NAV)
    main = write(
        tmp_path / "main.yaml",
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: root
          children:
            - {type: Subtree, name: go, options: {tree: nav}, inputs: {goal: [1.0, 1.0]}}
            - {type: Compare, name: far, options: {op: ">"}, inputs: {b: 1.0}}
        wires: [{from: root/go.distance, to: root/far.a}]
        subtrees:
          nav: {file: lib/nav.yaml}
        """,
    )
    tree = load_tree(main, registry)
    before = shape(tree)
    go = tree.find("root/go")
    assert isinstance(go, Subtree)
    assert set(go.input_ports) == {"goal"}
    assert set(go.output_ports) == {"distance"}
    assert tree.tick() is State.SUCCEEDED

    (tmp_path / "out").mkdir()
    copy = save_tree(tree, tmp_path / "out" / "main.json", registry)
    spec = read_tree_file(copy)
    assert spec.subtrees["nav"].file == "../lib/nav.yaml"
    assert shape(load_tree(copy, registry)) == before

    # the referenced file alone: its public input counts as given, and public survives
    nav = load_tree(tmp_path / "lib" / "nav.yaml", registry)
    assert file_info(nav).public == PublicSpec(
        inputs={"goal": "nav/move.goal"}, outputs={"distance": "nav/move.distance"}
    )
    assert dump_tree(nav, registry).public == file_info(nav).public


def test_subtree_file_including_itself_is_reported(tmp_path: Path) -> None:
    write(
        tmp_path / "a.yaml",
        """
        btcap: 1
        root: {type: Subtree, options: {tree: b}}
        subtrees: {b: {file: b.yaml}}
        """,
    )
    write(
        tmp_path / "b.yaml",
        """
        btcap: 1
        root: {type: Subtree, options: {tree: a}}
        subtrees: {a: {file: a.yaml}}
        """,
    )
    with pytest.raises(TreeFileError) as info:
        load_tree(tmp_path / "a.yaml")
    msg = str(info.value)
    assert msg.startswith(str(tmp_path / "a.yaml"))
    assert "subtree 'b'" in msg
    assert "includes itself" in msg


def test_problems_inside_a_subtree_file_name_both_files(tmp_path: Path) -> None:
    write(
        tmp_path / "inner.yaml",
        """
        btcap: 1
        root: {type: Wait, name: w, options: {seconds: never}}
        """,
    )
    outer = write(
        tmp_path / "outer.yaml",
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: inner}}
        subtrees: {inner: {file: inner.yaml}, gone: {file: missing.yaml}}
        """,
    )
    with pytest.raises(TreeFileError) as info:
        load_tree(outer)
    first, second = sorted(info.value.problems)
    assert first.startswith(f"{outer}: subtree 'gone' (file missing.yaml): ")
    assert "missing.yaml: cannot read" in first
    assert second.startswith(f"{outer}: subtree 'inner' (file inner.yaml): ")
    assert f"{tmp_path / 'inner.yaml'}: node 'w' option 'seconds': expected float" in second


def test_same_named_but_different_inner_trees_get_distinct_subtree_names() -> None:
    def inner(seconds: float) -> Tree:
        return Tree(Wait("w", seconds=seconds), name="pause")

    root = ReactiveSequence("root", children=[Subtree(inner(1.0), "a"), Subtree(inner(2.0), "b")])
    spec = dump_tree(Tree(root))
    assert sorted(spec.subtrees) == ["pause", "pause_2"]
    assert [c.options["tree"] for c in spec.root.children] == ["pause", "pause_2"]
    again = loads_tree(dumps_tree(spec))
    assert again.find("root/b").inner.root.options["seconds"] == 2.0  # type: ignore[attr-defined]


# -- errors ---------------------------------------------------------------------------
BAD_CASES: dict[str, tuple[str, list[str]]] = {
    "unknown node type": (
        """
        btcap: 1
        root: {type: ReactiveSequence, name: r, children: [{type: Sequnce, name: a}]}
        """,
        ["node 'r/a' field 'type'", "unknown node type 'Sequnce'", "did you mean Sequence"],
    ),
    "removed node type": (
        """
        btcap: 1
        root: {type: FallbackWithMemory, name: r, children: [{type: AlwaysSuccess}]}
        """,
        [
            "node 'r' field 'type'",
            "node type 'FallbackWithMemory': it was removed in btcap 0.2; use Fallback",
        ],
    ),
    "unknown option": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: Retry, name: a, options: {retrys: 2}, children: [{type: AlwaysSuccess}]}
        """,
        ["node 'r/a' option 'retrys'", "unknown option of Retry", "did you mean retries"],
    ),
    "bad option type": (
        """
        btcap: 1
        root: {type: Sequence, name: r, children: [{type: Wait, name: w, options: {seconds: soon}}]}
        """,
        ["node 'r/w' option 'seconds'", "expected float, got str 'soon'"],
    ),
    "missing required option": (
        """
        btcap: 1
        root: {type: ReactiveSequence, name: r, children: [{type: Wait, name: w}]}
        """,
        ["node 'r/w' option 'seconds'", "required (float) but missing"],
    ),
    "bad type name": (
        """
        btcap: 1
        root: {type: Constant, name: c, options: {value: 1, type: "lst[int]"}}
        """,
        ["node 'c' option 'type'", "unknown name 'lst'", "expected e.g."],
    ),
    "type option not a string": (
        """
        btcap: 1
        root: {type: Constant, name: c, options: {value: 1, type: 3}}
        """,
        ["node 'c' option 'type'", "expected a type name"],
    ),
    "constant value not of its type": (
        """
        btcap: 1
        root: {type: Constant, name: c, options: {value: x, type: int}}
        """,
        ["node 'c' field 'options'", "option 'value': expected int, got str"],
    ),
    "option rejected by the node": (
        """
        btcap: 1
        root: {type: Compare, name: c, options: {op: "~"}}
        """,
        ["node 'c' field 'options'", "expected one of ==, !="],
    ),
    "unknown input": (
        """
        btcap: 1
        root: {type: Compare, name: c, inputs: {z: 1}}
        """,
        ["node 'c' input 'z'", "Compare has no such input", "inputs: a, b"],
    ),
    "bad input value": (
        """
        btcap: 1
        root: {type: Move, name: m, inputs: {goal: [1.0, nope]}}
        """,
        ["node 'm' input 'goal'", "expected tuple[float, float]"],
    ),
    "required input without value or wire": (
        """
        btcap: 1
        root: {type: ReactiveSequence, name: r, children: [{type: Move, name: m}]}
        """,
        ["node 'r/m' input 'goal'", "required (tuple[float, float]) but has no value"],
    ),
    "duplicate sibling names": (
        """
        btcap: 1
        root: {type: Sequence, name: r, children: [{type: AlwaysSuccess}, {type: AlwaysSuccess}]}
        """,
        ["node 'r' field 'children[1]'", "a second child named 'AlwaysSuccess'"],
    ),
    "too many children": (
        """
        btcap: 1
        root:
          type: Inverter
          name: inv
          children: [{type: AlwaysSuccess, name: a}, {type: AlwaysSuccess, name: b}]
        """,
        ["node 'inv' field 'children'", "Inverter takes exactly 1 child, got 2"],
    ),
    "leaf with children": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: Wait, name: w, options: {seconds: 1}, children: [{type: AlwaysSuccess}]}
        """,
        ["node 'r/w' field 'children'", "Wait takes exactly 0 children, got 1"],
    ),
    "bad node name": (
        """
        btcap: 1
        root: {type: ReactiveSequence, name: r, children: [{type: AlwaysSuccess, name: a.b}]}
        """,
        ["node 'r/a.b' field 'name'", "without '/' or '.'"],
    ),
    "wire to an unknown port": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: Constant, name: c, options: {value: 1, type: int}}
            - {type: Log, name: l, options: {message: hi}}
        wires: [{from: r/c.value, to: r/l.nope}]
        """,
        ["wires[0] (r/c.value -> r/l.nope)", "'r/l' has no input 'nope'"],
    ),
    "wire to an unknown node": (
        """
        btcap: 1
        root: {type: Sequence, name: r, children: [{type: Log, name: l, options: {message: hi}}]}
        wires: [{from: r/x.value, to: r/l.value}]
        """,
        ["wires[0] (r/x.value -> r/l.value)", "no node 'r/x'"],
    ),
    "wire type mismatch": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: Constant, name: c, options: {value: x, type: str}}
            - {type: Move, name: m}
        wires: [{from: r/c.value, to: r/m.goal}]
        """,
        [
            "wires[0] (r/c.value -> r/m.goal)",
            "output is str but the input expects tuple[float, float]",
        ],
    ),
    "wire end without a port": (
        """
        btcap: 1
        root: {type: Sequence, name: r, children: [{type: Log, name: l, options: {message: hi}}]}
        wires: [{from: r/l, to: r/l.value}]
        """,
        ["wires[0] (r/l -> r/l.value) field 'from'", "is not 'node/path.port'"],
    ),
    "wire missing a field": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        wires: [{from: a.b}]
        """,
        ["field 'wires[0]'", "missing required field 'to'"],
    ),
    "unknown top-level key": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        wire: []
        """,
        ["top level", "unknown field 'wire'", "expected one of btcap, name"],
    ),
    "unknown node key": (
        """
        btcap: 1
        root: {type: Sequence, name: r, children: [{type: AlwaysSuccess, name: ok, option: {}}]}
        """,
        ["node 'r/ok'", "unknown field 'option'", "expected one of type, name, options"],
    ),
    "node key of the wrong type": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: AlwaysSuccess, name: ok}
            - {type: Inverter, children: [{type: AlwaysSuccess, options: [1]}]}
        """,
        ["node 'r/Inverter/AlwaysSuccess' field 'options'", "expected object, got array"],
    ),
    "missing node type": (
        """
        btcap: 1
        root: {type: ReactiveSequence, name: r, children: [{name: a}]}
        """,
        ["node 'r/a'", "missing required field 'type'"],
    ),
    "wrong version": (
        "btcap: 2\nroot: {type: AlwaysSuccess}\n",
        ["field 'btcap'", "unsupported schema version 2", "reads version 1"],
    ),
    "no version": (
        "root: {type: AlwaysSuccess}\n",
        ["field 'btcap'", "missing", "btcap: 1"],
    ),
    "malformed YAML": (
        "btcap: 1\nroot: {type: [AlwaysSuccess}\n",
        ["malformed YAML", "line 2"],
    ),
    "empty file": ("", ["the file is empty"]),
    "duplicate YAML key": (
        """
        btcap: 1
        root:
          type: ReactiveSequence
          children:
            - {type: Wait, options: {seconds: 1}, options: {seconds: 2}}
        """,
        ["line 5: duplicate key 'options'", "keep only the last one"],
    ),
    "subtree name not a string": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        subtrees: {1: {root: {type: AlwaysSuccess}}}
        """,
        ["key of field 'subtrees'", "expected str, got int"],
    ),
    "public port not a string": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        public: {inputs: {a: 3}}
        """,
        ["field 'public.inputs[...]'", "expected str, got int"],
    ),
    "not a mapping": ("- 1\n", ["top level", "expected a mapping", "got a list"]),
    "unknown subtree": (
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: nva}}
        subtrees: {nav: {root: {type: AlwaysSuccess}}}
        """,
        ["node 's' option 'tree'", "unknown subtree 'nva'", "did you mean nav"],
    ),
    "subtree with extra option": (
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: nav, rate: 2}}
        subtrees: {nav: {root: {type: AlwaysSuccess}}}
        """,
        ["node 's' option 'rate'", "unknown option of Subtree"],
    ),
    "recursive subtree": (
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: a}}
        subtrees:
          a: {root: {type: Subtree, name: x, options: {tree: b}}}
          b: {root: {type: Subtree, name: y, options: {tree: a}}}
        """,
        ["subtree 'b' node 'y' option 'tree'", "uses itself (a -> b -> a)"],
    ),
    "problem inside a subtree": (
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: nav}}
        subtrees:
          nav:
            root: {type: Sequence, name: n, children: [{type: Wait, name: w, options: {second: 1}}]}
        """,
        ["subtree 'nav' node 'n/w' option 'second'", "did you mean seconds"],
    ),
    "schema problem inside a subtree": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        subtrees:
          nav: {root: {type: ReactiveSequence, name: n, children: [{type: AlwaysSuccess, nam: x}]}}
        """,
        ["subtree 'nav' node 'n/AlwaysSuccess'", "unknown field 'nam'"],
    ),
    "subtree both inline and from a file": (
        """
        btcap: 1
        root: {type: AlwaysSuccess}
        subtrees: {nav: {file: x.yaml, root: {type: AlwaysSuccess}}}
        """,
        ["subtree 'nav' field 'root'", "not both"],
    ),
    "bad public port": (
        """
        btcap: 1
        root: {type: Subtree, name: s, options: {tree: nav}}
        subtrees:
          nav:
            root: {type: Move, name: m}
            public: {inputs: {goal: m.goal}, outputs: {far: m.goal}}
        """,
        ["subtree 'nav' field 'public.outputs.far'", "node 'm' has no output 'goal'"],
    ),
}


@pytest.mark.parametrize("case", list(BAD_CASES), ids=list(BAD_CASES))
def test_bad_file_errors_name_file_node_and_field(
    tmp_path: Path, registry: NodeRegistry, case: str
) -> None:
    text, expected = BAD_CASES[case]
    path = write(tmp_path / "bad_tree.yaml", text)
    with pytest.raises(TreeFileError) as info:
        load_tree(path, registry)
    msg = str(info.value)
    assert isinstance(info.value, TreeError)
    for line in info.value.problems:
        assert line.startswith(f"{path}: "), line
    for part in expected:
        assert part in msg, f"{part!r} not in {msg!r}"
    assert validate_file(path, registry) == info.value.problems


def test_a_json_file_with_fallback_with_memory_is_told_to_use_fallback(tmp_path: Path) -> None:
    path = tmp_path / "old.json"
    path.write_text(
        '{"btcap": 1, "root": {"type": "FallbackWithMemory", "name": "f", '
        '"children": [{"type": "AlwaysSuccess"}]}}'
    )
    with pytest.raises(TreeFileError) as info:
        load_tree(path)
    assert info.value.problems == [
        f"{path}: node 'f' field 'type': node type 'FallbackWithMemory': it was removed in "
        "btcap 0.2; use Fallback, which now resumes at the running child as "
        "FallbackWithMemory did (ReactiveFallback re-ticks from the first child every tick)"
    ]


def test_every_problem_of_a_file_is_reported_at_once(
    tmp_path: Path, registry: NodeRegistry
) -> None:
    path = write(
        tmp_path / "many.yaml",
        """
        btcap: 1
        root:
          type: ReactiveSequence
          name: r
          children:
            - {type: Wiat, name: a}
            - {type: Wait, name: b, options: {seconds: x}}
            - {type: Move, name: c}
            - {type: Log, name: d, options: {message: hi}}
        wires:
          - {from: r/a.value, to: r/d.value}
          - {from: r/d.value, to: r/d.value}
        """,
    )
    problems = validate_file(path, registry)
    assert len(problems) == 4, problems
    assert "node 'r/a' field 'type'" in problems[0]
    assert "node 'r/b' option 'seconds'" in problems[1]
    assert "wires[1]" in problems[2]  # wires[0] starts at a broken node: not reported again
    assert "node 'r/c' input 'goal'" in problems[3]


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_negative_durations_and_counts_are_refused_naming_file_node_and_option(
    tmp_path: Path, suffix: str
) -> None:
    def node(kind: str, name: str, **options: Any) -> dict[str, Any]:
        child = [{"type": "AlwaysSuccess"}] if kind != "Wait" else []
        return {"type": kind, "name": name, "options": options, "children": child}

    doc = {
        "btcap": 1,
        "root": {
            "type": "Sequence",
            "name": "r",
            "children": [
                node("Wait", "w", seconds=-5),
                node("Delay", "d", seconds=-0.5),
                node("Timeout", "t", seconds=0),
                node("Throttle", "th", rate_hz=-1),
                node("Retry", "re", retries=-1),
                node("Repeat", "rp", times=-2),
                node("Repeat", "ok", times=-1),  # documented: for ever
                node("RepeatUntilSuccess", "us", max_attempts=0),
                node("RepeatUntilFailure", "uf", max_attempts=-1),
            ],
        },
    }
    path = tmp_path / f"t{suffix}"
    path.write_text(json.dumps(doc))  # JSON is YAML too
    assert validate_file(path) == [
        f"{path}: node {where!r} option {option!r}: must be {rule}, got {value}"
        for where, option, rule, value in [
            ("r/w", "seconds", ">= 0", -5),
            ("r/d", "seconds", ">= 0", -0.5),
            ("r/t", "seconds", "> 0", 0),
            ("r/th", "rate_hz", "> 0", -1),
            ("r/re", "retries", ">= 0", -1),
            ("r/rp", "times", ">= -1", -2),
            ("r/us", "max_attempts", ">= 1", 0),
            ("r/uf", "max_attempts", ">= 1", -1),
        ]
    ]


def test_malformed_json_points_at_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    path.write_text('{"btcap": 1,\n "root": {"type": "AlwaysSuccess",}}')
    with pytest.raises(TreeFileError, match=r"t\.json: malformed JSON: .*line 2, column") as info:
        load_tree(path)
    assert str(info.value).startswith(str(path))


def test_json_schema_errors_are_translated_too(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    path.write_text(
        '{"btcap": 1, "root": {"type": "ReactiveSequence", "name": "r", "children": [{"type": 5}]}}'
    )
    with pytest.raises(TreeFileError, match=r"node 'r/\[0\]' field 'type': expected str, got int"):
        load_tree(path)


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("tree.txt", "unknown file type '.txt'; expected .yaml, .yml or .json"),
        ("gone.yaml", "cannot read"),
    ],
)
def test_unknown_suffix_and_missing_file(tmp_path: Path, name: str, match: str) -> None:
    path = tmp_path / name
    if name.endswith(".txt"):
        path.write_text("btcap: 1\n")
    with pytest.raises(TreeFileError, match=match) as info:
        load_tree(path)
    assert str(info.value).startswith(str(path))
    with pytest.raises(TreeFileError):
        save_tree(Tree(Wait("w", seconds=1.0)), tmp_path / "out.txt")


def test_loads_tree_labels_errors_and_rejects_unknown_formats() -> None:
    with pytest.raises(TreeFileError, match=r"^inline\.yaml: node 'x' field 'type'"):
        loads_tree("btcap: 1\nroot: {type: Nope, name: x}\n", name="inline.yaml")
    with pytest.raises(ValueError, match="expected 'yaml', 'json' or 'xml'"):
        loads_tree("{}", "toml")  # type: ignore[arg-type]
    tree = loads_tree('{"btcap": 1, "root": {"type": "AlwaysSuccess"}}', "json")
    assert tree.tick() is State.SUCCEEDED


# -- dumping trees that cannot be files -------------------------------------------------
async def _noop() -> None:
    return None


def test_dumping_a_node_built_from_a_callable_names_the_node() -> None:
    tree = Tree(ReactiveSequence("root", children=[Action(_noop, "act")]))
    with pytest.raises(
        TreeFileError, match=r"node 'root/act' field 'type': .*Action is not registered"
    ):
        dump_tree(tree)


def test_dumping_an_unencodable_value_or_unnamed_type_names_the_option() -> None:
    class Thing:
        pass

    with pytest.raises(TreeFileError, match=r"node 'c' option 'value': value .* cannot be written"):
        dump_tree(Tree(Constant("c", value=Thing())))
    with pytest.raises(
        TreeFileError, match=r"node 'c' option 'type': type .* has no name in files"
    ):
        dump_tree(Tree(Constant("c", value=None, type=Thing | None)))


@pytest.mark.parametrize("how", ["marker", "default"])
def test_type_valued_options_of_custom_nodes_round_trip(tmp_path: Path, how: str) -> None:
    class Typed(Leaf):
        if how == "marker":
            OPTIONS = {"kind": Port(Any, None, "a type, as marked by TYPE_OPTIONS")}
            TYPE_OPTIONS = frozenset({"kind"})
        else:
            OPTIONS = {"kind": Port(Any, float, "a type, as its default is one")}

        def on_tick(self) -> State:
            return State.SUCCEEDED

    reg = NodeRegistry([Typed])
    tree = Tree(Typed("p", kind=list[int] | None))
    path = save_tree(tree, tmp_path / "p.yaml", reg)
    assert "kind: 'list[int] | None'" in path.read_text()
    assert load_tree(path, reg).root.options["kind"] == list[int] | None


@pytest.mark.parametrize("fmt", ["json", "yaml"])
def test_nodes_nested_without_bound_are_refused_not_a_recursion_error(fmt: Any) -> None:
    """JSON nests in flow style and YAML too: 5000 Inverters deep is a clear refusal.

    Whoever notices the depth first (btcap, or a parser with a limit of its own, as
    PyYAML has since 6.0.4), the user gets one TreeFileError line naming the file.
    """
    text = '{"type": "AlwaysSuccess"}'
    for i in range(5000):
        text = f'{{"type": "Inverter", "name": "i{i}", "children": [{text}]}}'
    with pytest.raises(btcap.TreeFileError) as info:
        loads_tree(f'{{"btcap": 1, "root": {text}}}', fmt, name="deep")
    message = str(info.value)
    assert message.startswith("deep: ")
    assert "\n" not in message
    assert "nest" in message  # says why: nesting, in btcap's words or the parser's
