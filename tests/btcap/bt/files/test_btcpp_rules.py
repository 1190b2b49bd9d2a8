"""What BehaviorTree.CPP 4.8 checks when it loads a file: models of its own nodes, a
ReactiveSequence's children; and the SubTree error that follows an unknown type.

Where behaviortreepy (BehaviorTree.CPP 4.8) is installed, each file is also given to
BehaviorTree.CPP itself, which must accept or refuse it as btcap does.
"""

from __future__ import annotations

import textwrap

import pytest

from btcap import State, TreeFileError, default_registry, loads_tree
from btcap.bt.tree import Tree


def _xml(body: str) -> str:
    return (
        f'<root BTCPP_format="4" main_tree_to_execute="Main">\n'
        f"{textwrap.dedent(body).strip()}\n</root>\n"
    )


def _load(text: str) -> Tree:
    return loads_tree(text, "xml", default_registry(plugins=False), name="t.xml")


def _problems(text: str) -> list[str]:
    with pytest.raises(TreeFileError) as info:
        _load(text)
    return info.value.problems


def _btcpp_accepts(text: str) -> bool | None:
    """Whether BehaviorTree.CPP 4.8 creates the tree (None: behaviortreepy missing)."""
    try:
        import behaviortreepy as bt
    except ImportError:
        return None
    try:
        bt.BehaviorTreeFactory().create_tree_from_text(text)
    except RuntimeError:
        return False
    return True


# As BehaviorTree.CPP's own examples/test_files/log_test.xml and Groot-saved files do:
# models of built-ins with BehaviorTree.CPP's port names (none of them btcap's).
BUILTIN_MODELS = _xml(
    """
    <BehaviorTree ID="Main">
      <Sequence>
        <SubTree ID="Nap" name="first"/>
        <RetryUntilSuccessful num_attempts="2">
          <Repeat num_cycles="2">
            <Timeout msec="1000"><Delay delay_msec="0"><AlwaysSuccess/></Delay></Timeout>
          </Repeat>
        </RetryUntilSuccessful>
        <SetBlackboard value="3" output_key="n"/>
        <Script code="m := n"/>
      </Sequence>
    </BehaviorTree>
    <BehaviorTree ID="Nap">
      <Sequence name="NapSequence"><Sleep msec="0"/><AlwaysSuccess/></Sequence>
    </BehaviorTree>
    <TreeNodesModel>
      <Action ID="Sleep" editable="true"><input_port name="msec"/></Action>
      <Decorator ID="RetryUntilSuccessful">
        <input_port name="num_attempts" type="int">Execute again a failing child</input_port>
      </Decorator>
      <Decorator ID="Repeat"><input_port name="num_cycles" type="int"/></Decorator>
      <Decorator ID="Timeout"><input_port name="msec" type="unsigned int"/></Decorator>
      <Decorator ID="Delay"><input_port name="delay_msec" type="unsigned int"/></Decorator>
      <Action ID="SetBlackboard">
        <input_port name="value"/><inout_port name="output_key"/>
      </Action>
      <Action ID="Script"><input_port name="code" type="std::string"/></Action>
      <Control ID="Sequence"/>
    </TreeNodesModel>
    """
)


def test_models_of_built_ins_use_behaviortree_cpps_port_names() -> None:
    tree = _load(BUILTIN_MODELS)
    assert tree.tick_once() is State.SUCCEEDED
    assert _btcpp_accepts(BUILTIN_MODELS) in (True, None)


@pytest.mark.parametrize(
    ("model", "message"),
    [
        (
            '<Action ID="Sleep"><input_port name="seconds"/></Action>',
            "line 6: <TreeNodesModel> Action 'Sleep' input_port 'seconds': BehaviorTree.CPP's "
            "Sleep has no such port (its ports: msec (input))",
        ),
        (
            '<Decorator ID="Timeout"><output_port name="msec"/></Decorator>',
            "line 6: <TreeNodesModel> Decorator 'Timeout' output_port 'msec': "
            "BehaviorTree.CPP's Timeout port 'msec' is an input port",
        ),
        (
            '<Condition ID="Sleep"><input_port name="msec"/></Condition>',
            "line 6: <TreeNodesModel> Condition 'Sleep': BehaviorTree.CPP's Sleep is an "
            "Action, not a Condition",
        ),
    ],
    ids=["no such port", "output for an input", "another kind"],
)
def test_a_model_contradicting_a_built_in_is_refused_with_the_reason(
    model: str, message: str
) -> None:
    text = _xml(
        f"""
        <BehaviorTree ID="Main">
          <Sleep msec="0"/>
        </BehaviorTree>
        <TreeNodesModel>
        {model}
        </TreeNodesModel>
        """
    )
    assert _problems(text) == [f"t.xml: {message}"]


def test_a_reactive_sequence_with_two_async_sequences_is_refused_as_btcpp_does() -> None:
    text = _xml(
        """
        <BehaviorTree ID="Main">
          <ReactiveSequence>
            <AlwaysSuccess/>
            <AsyncSequence><AlwaysSuccess/></AsyncSequence>
            <AsyncSequence><AlwaysSuccess/></AsyncSequence>
          </ReactiveSequence>
        </BehaviorTree>
        """
    )
    assert _problems(text) == [
        't.xml: line 3: <ReactiveSequence>: BehaviorTree.CPP 4.8 refuses it: "A '
        'ReactiveSequence cannot have more than one async child." (<AsyncSequence> '
        "children at lines 5, 6)"
    ]
    assert _btcpp_accepts(text) in (False, None)
    # A ReactiveFallback is not checked, a nested AsyncSequence is not counted.
    allowed = text.replace("ReactiveSequence", "ReactiveFallback")
    assert _load(allowed).tick() is State.SUCCEEDED
    assert _btcpp_accepts(allowed) in (True, None)


def test_a_generic_element_below_a_reactive_sequence_is_refused_as_btcpp_does() -> None:
    text = _xml(
        """
        <BehaviorTree ID="Main">
          <ReactiveSequence>
            <Action ID="AlwaysSuccess"/>
          </ReactiveSequence>
        </BehaviorTree>
        """
    )
    assert _problems(text) == [
        "t.xml: line 4: <Action ID='AlwaysSuccess'> directly below a ReactiveSequence: "
        'BehaviorTree.CPP 4.8 refuses it ("Unknown node type: Action", its check of a '
        "ReactiveSequence's children reads the element name); write <AlwaysSuccess/>"
    ]
    assert _btcpp_accepts(text) in (False, None)
    compact = text.replace('<Action ID="AlwaysSuccess"/>', "<AlwaysSuccess/>")
    assert _load(compact).tick() is State.SUCCEEDED
    assert _btcpp_accepts(compact) in (True, None)


def test_an_unknown_type_in_a_subtree_is_the_only_error_about_its_ports() -> None:
    """The SubTree's ports are the unknown node's: no follow-on error before or after."""
    text = _xml(
        """
        <BehaviorTree ID="Main">
          <SubTree ID="Nav" target="{goal}" result="{path}"/>
        </BehaviorTree>
        <BehaviorTree ID="Nav">
          <Sequence>
            <AlwaysSuccess/>
            <Plan goal="{target}" path="{result}"/>
          </Sequence>
        </BehaviorTree>
        <TreeNodesModel>
          <SubTree ID="Nav"><input_port name="target"/><output_port name="result"/></SubTree>
        </TreeNodesModel>
        """
    )
    problems = _problems(text)
    assert len(problems) == 1
    assert problems[0].startswith("t.xml: line 8: <Plan>: unknown node type 'Plan'")
