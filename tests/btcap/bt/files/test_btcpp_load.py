"""BehaviorTree.CPP XML as BehaviorTree.CPP loads it: names, documents, stubs, errors.

Names as in the file (btcap-only built-ins never capture an element), anonymous trees,
``<include>``, the format attribute, choosing the main tree, built-ins btcap does not
map, stand-ins built from ``<TreeNodesModel>`` and the one-line unknown-type report.
The Nav2-shaped files of ``examples/nav2/`` were written for btcap.
"""

from __future__ import annotations

import textwrap
import warnings
from pathlib import Path
from typing import Any

import anyio
import pytest

from btcap import (
    Leaf,
    Node,
    Port,
    State,
    Subtree,
    Tree,
    TreeFileError,
    default_registry,
    dumps_tree,
    load_tree,
    loads_tree,
)
from btcap.actors import ManualClock
from btcap.bt.files import TreeFileWarning, validate_file
from btcap.bt.files.btcpp_stubs import cpp_type
from btcap.bt.registry import NodeRegistry

NAV2 = Path(__file__).resolve().parents[4] / "examples" / "nav2"
NAV_TREE = NAV2 / "navigate_w_replanning_and_recovery.xml"
NAV_MODEL = NAV2 / "nav2_tree_nodes.xml"
DRY_RUN = NAV2 / "dry_run.xml"


class Wait(Leaf):
    """Nav2's Wait as a user registers it: nothing like btcap's own Wait."""

    INPUTS = {"wait_duration": float}

    def on_tick(self) -> State:
        return State.SUCCEEDED


def _xml(body: str, head: str = 'BTCPP_format="4"') -> str:
    return f"<root {head}>\n{textwrap.dedent(body).strip()}\n</root>\n"


def _load(text: str, registry: NodeRegistry | None = None, **kw: Any) -> Tree:
    reg = registry if registry is not None else default_registry(plugins=False)
    return loads_tree(text, "xml", reg, name="t.xml", **kw)


def _problems(text: str, **kw: Any) -> list[str]:
    with pytest.raises(TreeFileError) as info:
        _load(text, **kw)
    return info.value.problems


async def _run(tree: Tree, clock: ManualClock) -> State:
    """Tick to a result; the caller shuts the tree down after looking at it."""
    with anyio.fail_after(10):
        async with clock.autojump():
            return await tree.run(10.0)


def _inner(tree: Tree, path: str) -> Tree:
    sub = tree.find(path)
    assert isinstance(sub, Subtree)
    return sub.inner


# -- names as in the file ---------------------------------------------------------------
def test_a_btcap_only_builtin_never_captures_an_xml_element() -> None:
    text = _xml('<BehaviorTree ID="M"><Wait wait_duration="5.0"/></BehaviorTree>')
    (problem,) = _problems(text)
    assert "<Wait>: unknown node type 'Wait' (1 element, line 2)" in problem
    assert "no port" not in problem  # not read as btcap's Wait


def test_the_users_type_named_like_a_btcap_builtin_builds_from_xml() -> None:
    reg = default_registry(plugins=False)
    reg.register(Wait)
    tree = _load(_xml('<BehaviorTree ID="M"><Wait wait_duration="5.0"/></BehaviorTree>'), reg)
    assert type(tree.root) is Wait
    assert tree.root.inputs["wait_duration"] == 5.0
    # ...while YAML keeps btcap's Wait by its plain name, and reaches the user's as user.Wait
    yml = "btcap: 1\nroot: {type: Sequence, children: [{type: Wait, options: {seconds: 1}}]}\n"
    assert type(loads_tree(yml, "yaml", reg).root.children[0]).__module__ == "btcap.bt.leaves"
    yml = "btcap: 1\nroot: {type: user.Wait, inputs: {wait_duration: 2.0}}\n"
    assert type(loads_tree(yml, "yaml", reg).root) is Wait


def test_btcap_builtins_are_spelt_with_their_prefix_in_xml() -> None:
    tree = _load(_xml('<BehaviorTree ID="M"><btcap.Log message="hi"/></BehaviorTree>'))
    assert type(tree.root).__name__ == "Log"
    assert tree.root.name == "Log"


@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("TryCatch", "BehaviorTree.CPP's TryCatch has no btcap equivalent: btcap has no node"),
        ("WasEntryUpdated", "BehaviorTree.CPP's WasEntryUpdated has no btcap equivalent"),
    ],
)
def test_unmapped_btcpp_builtins_are_refused_as_builtins_not_unknown(
    kind: str, message: str
) -> None:
    reg = default_registry(plugins=False)
    reg.register(type(kind, (Leaf,), {"on_tick": lambda self: State.SUCCEEDED}))
    (problem,) = _problems(_xml(f'<BehaviorTree ID="M"><{kind}/></BehaviorTree>'), registry=reg)
    assert message in problem  # a type of the user's may not stand in for a built-in
    assert "unknown" not in problem


# -- documents --------------------------------------------------------------------------
def test_an_anonymous_single_tree_loads_as_behaviortree_cpp_names_it() -> None:
    tree = _load(_xml("<BehaviorTree><AlwaysSuccess/></BehaviorTree>"))
    assert tree.name == "BehaviorTree_0"


def test_a_missing_format_warns_and_loads() -> None:
    text = "<root><BehaviorTree><AlwaysSuccess/></BehaviorTree></root>"
    with pytest.warns(TreeFileWarning, match=r"t.xml: line 1: <root> has no BTCPP_format"):
        _load(text)


def test_format_3_is_refused_with_the_reason() -> None:
    (problem,) = _problems(_xml("<BehaviorTree/>", 'BTCPP_format="3"'))
    assert "BehaviorTree.CPP 3.x files name nodes and ports differently" in problem


TWO = _xml(
    '<BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>\n'
    '<BehaviorTree ID="B"><AlwaysFailure/></BehaviorTree>'
)


def test_main_chooses_among_several_trees() -> None:
    (problem,) = _problems(TWO)
    assert "2 BehaviorTrees (A, B); say which one to run (--main TREE, or main=" in problem
    assert type(_load(TWO, main="B").root).__name__ == "AlwaysFailure"
    (problem,) = _problems(TWO, main="C")
    assert "main tree 'C': no such BehaviorTree (A, B)" in problem
    over = TWO.replace("<root ", '<root main_tree_to_execute="A" ')
    assert _load(over, main="B").name == "B"  # as createTree(name) overrides it


def _write(folder: Path, name: str, body: str, head: str = 'BTCPP_format="4"') -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_xml(body, head))
    return path


def test_include_is_relative_to_the_including_file(tmp_path: Path) -> None:
    _write(tmp_path / "sub", "leaf.xml", '<BehaviorTree ID="Leaf"><AlwaysFailure/></BehaviorTree>')
    _write(
        tmp_path / "sub",
        "mid.xml",
        '<include path="leaf.xml"/>\n<BehaviorTree ID="Mid"><SubTree ID="Leaf"/></BehaviorTree>',
    )
    main = _write(
        tmp_path,
        "main.xml",
        '<include path="sub/mid.xml"/>\n'
        '<BehaviorTree ID="Main"><Inverter><SubTree ID="Mid"/></Inverter></BehaviorTree>',
        'BTCPP_format="4" main_tree_to_execute="Main"',
    )
    tree = load_tree(main, default_registry(plugins=False))
    assert tree.name == "Main"
    # Text finds includes through base=, as a file does through its folder.
    text = main.read_text()
    assert _load(text, base=tmp_path).name == "Main"


def test_include_problems_name_the_included_file(tmp_path: Path) -> None:
    inner = _write(tmp_path, "inner.xml", '<BehaviorTree ID="In">\n<Wiggle/>\n</BehaviorTree>')
    main = _write(
        tmp_path,
        "main.xml",
        '<include path="inner.xml"/>\n<BehaviorTree ID="Main"><SubTree ID="In"/></BehaviorTree>',
        'BTCPP_format="4" main_tree_to_execute="Main"',
    )
    problems = validate_file(main, default_registry(plugins=False))
    assert problems[0].startswith(f"{inner}: line 3: <Wiggle>: unknown node type 'Wiggle'")


@pytest.mark.parametrize(
    ("attrs", "message"),
    [
        ('path="nope.xml"', "no such file"),
        ('ros_pkg="nav2_bt_navigator" path="x.xml"', "btcap does not look up ROS packages"),
        ("", "<include> without a path"),
    ],
)
def test_bad_includes_are_refused(tmp_path: Path, attrs: str, message: str) -> None:
    main = _write(
        tmp_path, "m.xml", f"<include {attrs}/>\n<BehaviorTree><AlwaysSuccess/></BehaviorTree>"
    )
    (problem,) = validate_file(main, default_registry(plugins=False))
    assert problem.startswith(f"{main}: line 2: ")
    assert message in problem


def test_an_include_cycle_is_refused_naming_the_chain(tmp_path: Path) -> None:
    a = _write(
        tmp_path,
        "a.xml",
        '<include path="b.xml"/>\n<BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>',
    )
    b = _write(tmp_path, "b.xml", '<include path="a.xml"/>')
    (problem,) = validate_file(a, default_registry(plugins=False))
    assert problem == (
        f"{b}: line 2: <include path='a.xml'>: includes itself "
        f"({a.resolve()} -> {b.resolve()} -> {a.resolve()})"
    )


def test_the_same_tree_id_in_two_files_is_refused(tmp_path: Path) -> None:
    other = _write(tmp_path, "o.xml", '<BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree>')
    main = _write(
        tmp_path,
        "m.xml",
        '<include path="o.xml"/>\n<BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree>',
    )
    (problem,) = validate_file(main, default_registry(plugins=False))
    assert f"a second <BehaviorTree ID='T'> (the first is at {other} line 2)" in problem


# -- errors people read once ------------------------------------------------------------
def test_unknown_types_are_one_line_each_with_count_and_first_lines() -> None:
    many = "\n".join(f'<Wiggle name="w{i}"/>' for i in range(33))
    text = _xml(
        f'<BehaviorTree ID="M">\n<Sequence>\n{many}\n<Jiggle/>\n</Sequence>\n</BehaviorTree>'
    )
    problems = _problems(text)
    assert problems == [
        "t.xml: line 4: <Wiggle>: unknown node type 'Wiggle' "
        "(33 elements, lines 4, 5, 6, 7, 8, ...)",
        "t.xml: line 37: <Jiggle>: unknown node type 'Jiggle' (1 element, line 37)",
        "t.xml: 2 unknown node types: register them (--load MODULE) or declare capability "
        "interfaces of those names (--interfaces FILE), or declare them in <TreeNodesModel> "
        "(or --model FILE) and add --stub-missing",
    ]
    assert all(len(p) < 250 for p in problems)  # no list of btcap's own types


# -- stubs from <TreeNodesModel> --------------------------------------------------------
MODELLED = _xml(
    """
    <BehaviorTree ID="M">
      <Retry3>
        <Sequence>
          <Plan goal="1.5" path="{path}"/>
          <Follow path="{path}"/>
        </Sequence>
      </Retry3>
    </BehaviorTree>
    <TreeNodesModel>
      <Decorator ID="Retry3"/>
      <Action ID="Plan">
        <input_port name="goal" type="double"/>
        <input_port name="planner" type="std::string" default="GridBased"/>
        <output_port name="path" type="nav_msgs::msg::Path"/>
      </Action>
      <Action ID="Follow">
        <input_port name="path"/>
        <input_port name="goal" default="{goal}"/>
      </Action>
    </TreeNodesModel>
    """
)


def test_stubs_are_built_from_the_model_with_typed_ports() -> None:
    assert "unknown node type 'Plan'" in "\n".join(_problems(MODELLED))
    tree = _load(MODELLED, stub_missing=True)
    plan = tree.find("Retry3/Sequence/Plan")
    assert isinstance(plan, Node)
    assert plan.input_ports["goal"].type == float | None
    assert plan.inputs == {"goal": 1.5, "planner": "GridBased"}
    assert plan.output_ports["path"].type is Any  # a C++ type btcap cannot know
    # A default naming an entry is no literal: the stub's input stays unset.
    assert tree.find("Retry3/Sequence/Follow").inputs["goal"] is None


def test_a_stubbed_port_keeps_its_model_type_against_literals() -> None:
    bad = MODELLED.replace('goal="1.5"', 'goal="far"')
    assert any("input 'goal'" in p for p in _problems(bad, stub_missing=True))


async def test_stubs_succeed_by_default_and_follow_their_script() -> None:
    clock = ManualClock()
    tree = _load(MODELLED, stub_missing=True, clock=clock)
    assert await _run(tree, clock) is State.SUCCEEDED
    await tree.shutdown()
    script = {
        "types": {"Plan": ["RUNNING", "RUNNING", "SUCCESS"]},
        "names": {"Fol*": {"results": "FAILURE"}},
    }
    clock = ManualClock()
    tree = _load(MODELLED, stub_missing=True, stub_script=script, clock=clock)
    assert await _run(tree, clock) is State.FAILED  # the decorator stub passes it on
    assert tree.find("Retry3/Sequence/Follow").state is State.FAILED
    await tree.shutdown()


async def test_a_script_sets_outputs_when_the_stub_finishes() -> None:
    clock = ManualClock()
    script = {"names": {"Plan": {"results": ["RUNNING", "SUCCESS"], "outputs": {"path": [1, 2]}}}}
    tree = _load(MODELLED, stub_missing=True, stub_script=script, clock=clock)
    with anyio.fail_after(10):
        assert tree.tick() is State.RUNNING
        assert tree.find("Retry3/Sequence/Plan").outputs["path"] is None
        assert tree.tick() is State.SUCCEEDED
        assert tree.find("Retry3/Sequence/Follow").inputs["path"] == [1, 2]
        await tree.shutdown()


@pytest.mark.parametrize(
    ("script", "message"),
    [
        ({"types": {"Plan": "MAYBE"}}, "stub script: types.Plan: 'MAYBE': expected SUCCESS"),
        ({"type": {}}, "stub script: 'type': expected default, types or names"),
        ({"types": {"Retry3": "FAILURE"}}, "Retry3 is a Decorator; scripts set what actions"),
        ({"names": {"Plan": {"outputs": {"route": 1}}}}, "output 'route': the model declares"),
    ],
)
def test_bad_stub_scripts_are_refused(script: dict[str, Any], message: str) -> None:
    assert any(message in p for p in _problems(MODELLED, stub_missing=True, stub_script=script))


def test_a_stub_script_file_is_read(tmp_path: Path) -> None:
    path = tmp_path / "script.yaml"
    path.write_text("default: FAILURE\n")
    tree = _load(MODELLED, stub_missing=True, stub_script=path)
    assert type(tree.find("Retry3/Sequence/Plan")).__name__ == "Plan"
    path.write_text("default: [\n")
    assert any(str(path) in p for p in _problems(MODELLED, stub_missing=True, stub_script=path))


def test_registered_types_win_over_stubs() -> None:
    reg = default_registry(plugins=False)

    class Follow(Leaf):
        INPUTS = {"path": Any, "goal": Port(Any, None)}

        def on_tick(self) -> State:
            return State.SUCCEEDED

    reg.register(Follow)
    tree = _load(MODELLED, reg, stub_missing=True)
    assert type(tree.find("Retry3/Sequence/Follow")) is Follow
    assert "Follow" in reg
    assert "Plan" not in reg


def test_nav2_tree_validates_from_its_files_alone() -> None:
    reg = default_registry(plugins=False)
    assert validate_file(DRY_RUN, reg, stub_missing=True, models=[NAV_MODEL]) == []
    # The navigation tree alone reads {goal}, which Nav2's navigator supplies before the
    # first tick: the file is valid, and the application gives the entry.
    assert validate_file(NAV_TREE, reg, stub_missing=True, models=[NAV_MODEL]) == []
    alone = load_tree(NAV_TREE, reg, stub_missing=True, models=[NAV_MODEL], entries={"goal": "1;2"})
    assert alone.blackboard["goal"] == "1;2"
    # Nav2's own Wait is stubbed from its model, not taken for btcap's Wait.
    tree = load_tree(DRY_RUN, reg, stub_missing=True, models=[NAV_MODEL])
    nav = _inner(tree, "Sequence/NavigateWithReplanning")
    wait = nav.find("NavigateRecovery/Sequence/RecoveryFallback/RecoveryActions/Wait")
    assert type(wait).__name__ == "Wait"
    assert wait.inputs["wait_duration"] == "5.0"


async def test_nav2_tree_dry_runs_with_a_script() -> None:
    clock = ManualClock()
    script = {"types": {"ComputePathToPose": ["RUNNING", "SUCCESS"], "FollowPath": "FAILURE"}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the model file has no BTCPP_format: no warning
        tree = load_tree(
            DRY_RUN,
            default_registry(plugins=False),
            clock=clock,
            stub_missing=True,
            models=[NAV_MODEL],
            stub_script=script,
        )
    assert await _run(tree, clock) is State.FAILED  # FollowPath fails, recoveries spent
    nav = _inner(tree, "Sequence/NavigateWithReplanning")
    assert nav.find("NavigateRecovery").state is State.FAILED  # Nav2's RecoveryNode
    await tree.shutdown()


def test_a_users_builtin_named_type_dumps_as_user_name_and_loads_back() -> None:
    reg = default_registry(plugins=False)
    reg.register(Wait)
    tree = _load(_xml('<BehaviorTree ID="M"><Wait wait_duration="5.0"/></BehaviorTree>'), reg)
    text = dumps_tree(tree, registry=reg)
    assert "type: user.Wait" in text
    again = loads_tree(text, "yaml", reg)
    assert type(again.root) is Wait
    assert again.root.name == "Wait"


def test_an_inout_port_of_a_model_is_an_input_and_an_output_of_its_stub() -> None:
    text = _xml(
        """
        <BehaviorTree ID="M"><Prune goals="a;b"/></BehaviorTree>
        <TreeNodesModel>
          <Action ID="Prune"><inout_port name="goals" type="std::vector&lt;Pose&gt;"/></Action>
        </TreeNodesModel>
        """
    )
    prune = _load(text, stub_missing=True).root
    assert set(prune.input_ports) == set(prune.output_ports) == {"goals"}
    assert prune.inputs["goals"] == "a;b"  # an unknown C++ type: the text as it is


def test_malformed_included_and_model_files_are_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text('<root BTCPP_format="4">\n<BehaviorTree>\n</root>\n')
    main = _write(tmp_path, "m.xml", '<include path="bad.xml"/>\n<BehaviorTree ID="M"/>')
    problems = validate_file(main, default_registry(plugins=False))
    assert problems[0].startswith(f"{bad}: line 3: malformed XML")
    empty = _write(tmp_path, "model.xml", "", "")
    problems = validate_file(main, default_registry(plugins=False), models=[empty])
    assert f"{empty}: line 1: no <TreeNodesModel> in this model file" in problems


@pytest.mark.parametrize(
    ("text", "tp"),
    [
        ("double", float),
        ("unsigned int", int),
        ("std::__cxx11::basic_string<char, std::char_traits<char>, std::allocator<char> >", str),
        ("geometry_msgs::msg::PoseStamped_<std::allocator<void> >", Any),
        (None, Any),
    ],
)
def test_model_types_btcap_knows_and_the_rest(text: str | None, tp: Any) -> None:
    assert cpp_type(text) is tp


async def test_undeclared_types_are_stubbed_from_their_use_with_a_warning() -> None:
    """BehaviorTree.CPP's tutorials ship no <TreeNodesModel>: the use says enough."""
    text = _xml(
        """
        <BehaviorTree ID="M">
          <Sequence>
            <SaySomething message="hello"/>
            <RetryOnce><Action ID="OpenGripper" force="2"/></RetryOnce>
            <Both><SaySomething message="again" volume="3"/><AlwaysSuccess/></Both>
          </Sequence>
        </BehaviorTree>
        """
    )
    assert len(_problems(text)) == 5  # four unknown types, and what to do
    clock = ManualClock()
    with pytest.warns(TreeFileWarning) as caught:
        tree = _load(text, stub_missing=True, clock=clock)
    assert [str(w.message) for w in caught] == [
        "t.xml: line 4: SaySomething is declared in no <TreeNodesModel>; stubbed from its "
        "use (Action; inputs: message, volume)",
        "t.xml: line 5: RetryOnce is declared in no <TreeNodesModel>; stubbed from its use "
        "(Decorator; inputs: none)",
        "t.xml: line 5: OpenGripper is declared in no <TreeNodesModel>; stubbed from its use "
        "(Action; inputs: force)",
        "t.xml: line 6: Both is a Control btcap does not know: its stand-in ticks its "
        "children as a Sequence",
        "t.xml: line 6: Both is declared in no <TreeNodesModel>; stubbed from its use "
        "(Control; inputs: none)",
    ]
    assert tree.find("Sequence/SaySomething").inputs == {"message": "hello", "volume": None}
    assert await _run(tree, clock) is State.SUCCEEDED
    await tree.shutdown()


async def test_a_name_pattern_matches_the_node_path_too() -> None:
    clock = ManualClock()
    script = {"names": {"Retry3/*/Fol*": "FAILURE"}}
    tree = _load(MODELLED, stub_missing=True, stub_script=script, clock=clock)
    assert await _run(tree, clock) is State.FAILED
    await tree.shutdown()
