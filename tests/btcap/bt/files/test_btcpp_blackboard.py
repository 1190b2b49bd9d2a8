"""BehaviorTree.CPP's blackboard in XML trees: entries the application supplies, several
writers (the last write wins), a node reading and writing one entry, ``{@key}`` root
entries, SubTree remapping of entries, and what is refused."""

from __future__ import annotations

import textwrap
from typing import Any

import pytest

from btcap import (
    Leaf,
    NodeRegistry,
    State,
    Tree,
    TreeFileError,
    default_registry,
    dumps_tree,
    loads_tree,
)
from btcap.bt.blackboard import Blackboard
from btcap.bt.empty import NoValues
from btcap.bt.state import TreeError


class Move(Leaf):
    """A typed input and output: the distance to ``goal``."""

    INPUTS = {"goal": tuple[float, float]}
    OUTPUTS = {"distance": float}

    def on_tick(self) -> State:
        x, y = self.inputs["goal"]
        self.outputs["distance"] = abs(x) + abs(y)
        return State.SUCCEEDED


class Prune(Leaf):
    """Like Nav2's RemovePassedGoals: reads a list and writes it back without its head."""

    INPUTS = {"input_goals": list[int]}
    OUTPUTS = {"output_goals": list[int]}

    def on_tick(self) -> State:
        self.outputs["output_goals"] = self.inputs["input_goals"][1:]
        return State.SUCCEEDED


class Fail(Leaf):
    """Sets an error code and fails, as a Nav2 action does."""

    OUTPUTS = {"error_code": int}
    OPTIONS = {"code": int}

    def on_tick(self) -> State:
        self.outputs["error_code"] = self.options["code"]
        return State.FAILED


class Count(Leaf):
    """Writes how often it ticked (a reset starts it over)."""

    OUTPUTS = {"n": int}

    def on_tick(self) -> State:
        self.outputs["n"] = (self.outputs["n"] or 0) + 1
        return State.SUCCEEDED


class Seen(Leaf):
    """Records every value its input reads (in the module list SEEN)."""

    INPUTS = {"value": Any}

    def on_tick(self) -> State:
        SEEN.append(self.inputs["value"])
        return State.SUCCEEDED


class Maybe(Leaf):
    """An input with a default: a missing entry gives the default, not a failure."""

    INPUTS = {"value": int | None}

    def on_tick(self) -> State:
        SEEN.append(self.inputs["value"])
        return State.SUCCEEDED


SEEN: list[Any] = []


@pytest.fixture(autouse=True)
def _clear_seen() -> None:
    SEEN.clear()


def _registry() -> NodeRegistry:
    reg = default_registry(plugins=False)
    for cls in (Move, Prune, Fail, Seen, Maybe, Count):
        reg.register(cls)
    return reg


def _xml(body: str) -> str:
    return (
        f'<root BTCPP_format="4" main_tree_to_execute="Main">\n'
        f"{textwrap.dedent(body).strip()}\n</root>\n"
    )


def _board(tree: Tree) -> Blackboard:
    assert tree.blackboard is not None
    return tree.blackboard


def _load(body: str, **entries: Any) -> Tree:
    return loads_tree(_xml(body), "xml", _registry(), name="t.xml", entries=entries)


PRUNE = """
    <BehaviorTree ID="Main">
      <Sequence>
        <Prune input_goals="{goals}" output_goals="{goals}"/>
        <Seen value="{goals}"/>
      </Sequence>
    </BehaviorTree>
"""


def test_a_node_reading_and_writing_one_entry_reads_the_applications_value_first() -> None:
    """Nav2's RemovePassedGoals: the input is not wired to the node's own output."""
    tree = _load(PRUNE, goals=[1, 2, 3])
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [[2, 3]]
    assert _board(tree)["goals"] == [2, 3]
    tree.reset()  # a reset keeps entries, as BehaviorTree.CPP's halt does
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [[2, 3], [3]]


def test_a_read_of_an_entry_nothing_wrote_fails_the_node_as_get_input_fails() -> None:
    tree = _load(PRUNE)
    assert tree.tick() is State.FAILED  # btcap's Sequence fails on a child in error
    prune = tree.find("Sequence/Prune")
    assert prune.state is State.ERROR
    error = prune.error
    assert "blackboard entry {goals} has no value" in str(error)
    assert SEEN == []


def test_an_input_with_a_default_reads_its_default_from_a_missing_entry() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence><Maybe value="{v}"/><Fail code="3" error_code="{v}"/></Sequence>
        </BehaviorTree>
        """
    )
    assert tree.tick() is State.FAILED
    assert SEEN == [None]


GOAL = """
    <BehaviorTree ID="Main">
      <Sequence>
        <Move goal="{goal}" distance="{d}"/>
        <Seen value="{d}"/>
      </Sequence>
    </BehaviorTree>
"""


def test_the_application_supplies_an_entry_nodes_only_read() -> None:
    tree = _load(GOAL, goal="1;2")  # text is read as the entry's type, as BT.CPP does
    assert _board(tree)["goal"] == (1.0, 2.0)
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [3.0]

    later = _load(GOAL)
    _board(later)["goal"] = [3, 4]
    assert later.tick() is State.SUCCEEDED
    assert SEEN == [3.0, 7.0]


def test_an_entry_read_but_never_written_nor_set_is_refused_before_ticking() -> None:
    tree = _load(GOAL)
    with pytest.raises(TreeError, match=r"\{goal\} \(tuple\[float, float\], read by Sequence/Move"):
        tree.tick()


def test_supplied_values_are_checked_against_the_entry_type() -> None:
    with pytest.raises(
        TreeFileError, match=r"t.xml: blackboard entry 'goal' of tree 'Main': expected tuple"
    ):
        _load(GOAL, goal="north")
    board = _board(_load(GOAL))
    with pytest.raises(TreeError, match="entry 'goal'"):
        board["goal"] = "north"
    with pytest.raises(TreeError, match=r"no entry 'gaol' .*\(entries: goal\)"):
        board["gaol"] = (1, 2)


def test_an_entry_several_nodes_write_holds_the_last_write() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <Fallback>
              <Fail code="1" error_code="{error}"/>
              <Sequence><Seen value="{error}"/><Fail code="2" error_code="{error}"/></Sequence>
              <Seen value="{error}"/>
            </Fallback>
            <Seen value="{error}"/>
          </Sequence>
        </BehaviorTree>
        """
    )
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [1, 2, 2]


def test_an_entry_the_application_supplies_and_a_node_writes_starts_with_the_supplied_value() -> (
    None
):
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <Seen value="{d}"/>
            <Move goal="1;2" distance="{d}"/>
            <Seen value="{d}"/>
          </Sequence>
        </BehaviorTree>
        """,
        d=9,
    )
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [9, 3.0]


SUBTREE = """
    <BehaviorTree ID="Main">
      <Sequence>
        {use}
        <Seen value="{{todo}}"/>
      </Sequence>
    </BehaviorTree>
    <BehaviorTree ID="PruneIt">
      <Sequence>
        <Prune input_goals="{{goals}}" output_goals="{{goals}}"/>
        <Seen value="{{goals}}"/>
      </Sequence>
    </BehaviorTree>
"""


@pytest.mark.parametrize(
    ("use", "key"),
    [
        ('<SubTree ID="PruneIt" goals="{todo}"/>', "todo"),
        ('<SubTree ID="PruneIt" _autoremap="true"/>', "goals"),
    ],
)
def test_a_subtree_entry_remapped_is_the_parents_entry(use: str, key: str) -> None:
    body = SUBTREE.format(use=use).replace("{todo}", "{" + key + "}")
    tree = _load(body, **{key: [1, 2, 3]})
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [[2, 3], [2, 3]]
    assert _board(tree)[key] == [2, 3]


def test_a_subtree_entry_given_a_literal_starts_with_it_and_stays_inside() -> None:
    body = SUBTREE.format(use='<SubTree ID="PruneIt" goals="5;6;7"/>')
    tree = _load(body, todo=[0])
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [[6, 7], [0]]


def test_root_entries_are_shared_with_subtrees() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <SubTree ID="Go"/>
            <Seen value="{d}"/>
            <Seen value="{@d}"/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Go">
          <Move goal="{@goal}" distance="{@d}"/>
        </BehaviorTree>
        """,
        goal=(2, 2),
    )
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [4.0, 4.0]


def test_a_subtree_output_into_a_shared_entry_is_written_by_the_node_inside() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Fallback>
            <Fail code="1" error_code="{error}"/>
            <SubTree ID="Other" code="{error}"/>
            <Seen value="{error}"/>
          </Fallback>
        </BehaviorTree>
        <BehaviorTree ID="Other">
          <Sequence><Seen value="{code}"/><Fail code="2" error_code="{code}"/></Sequence>
        </BehaviorTree>
        """
    )
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [1, 2]
    assert _board(tree)["error"] == 2


def test_a_tree_without_blackboard_entries_pays_nothing_for_them() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence><Move goal="1;2" distance="{d}"/><Seen value="{d}"/></Sequence>
        </BehaviorTree>
        """
    )
    assert [f"{w.source.path} -> {w.target.path}" for w in tree.wires] == [
        "Sequence/Move -> Sequence/Seen"
    ]
    # No node writes through the blackboard: outputs are plain (or btcap's shared empty).
    assert all(type(n.outputs) in (dict, NoValues) for n in tree.nodes())
    assert list(_board(tree)) == []


def test_entries_are_refused_for_btcap_tree_files() -> None:
    text = "btcap: 1\nroot: {type: AlwaysSuccess}\n"
    with pytest.raises(TreeFileError, match=r"<string>: blackboard entries \(goal\) are for"):
        loads_tree(text, "yaml", _registry(), entries={"goal": 1})


def test_a_tree_with_blackboard_entries_is_not_written_as_a_btcap_file() -> None:
    with pytest.raises(
        TreeFileError, match=r"tree 'Main' uses BehaviorTree.CPP blackboard entries"
    ):
        dumps_tree(_load(PRUNE, goals=[1]), registry=_registry())


def test_an_entry_keeps_its_value_across_a_loop_where_a_wire_would_be_cleared() -> None:
    """Read before it is written in each cycle: BehaviorTree.CPP reads the last cycle's
    value (a wire would read the writer's output, cleared when the Repeat resets it)."""
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Repeat num_cycles="3">
            <Sequence><Maybe value="{d}"/><Count n="{d}"/></Sequence>
          </Repeat>
        </BehaviorTree>
        """
    )
    assert tree.wires == []
    tree.tick_until_result()
    assert SEEN == [None, 1, 1]


def test_a_reader_ticking_only_after_its_writer_succeeded_is_wired() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <Timeout msec="1000"><Sequence><Move goal="1;2" distance="{d}"/></Sequence></Timeout>
            <Seen value="{d}"/>
            <Fallback><Move goal="1;1" distance="{e}"/><AlwaysSuccess/></Fallback>
            <Seen value="{e}"/>
          </Sequence>
        </BehaviorTree>
        """
    )
    wired = [f"{w.source.path} -> {w.target.path}" for w in tree.wires]
    assert wired == ["Sequence/Timeout/Sequence/Move -> Sequence/Seen"]
    assert list(_board(tree)) == ["e"]  # a Fallback may succeed without its writer
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [3.0, 2.0]


def test_entries_pass_through_nested_subtrees_and_root_remaps() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <SubTree ID="A" list="{todo}"/>
            <Seen value="{todo}"/>
            <SubTree ID="C" g="{@todo}"/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="A"><SubTree ID="B" goals="{list}"/></BehaviorTree>
        <BehaviorTree ID="B"><Prune input_goals="{goals}" output_goals="{goals}"/></BehaviorTree>
        <BehaviorTree ID="C">
          <Sequence>
            <Seen value="{g}"/>
            <Prune input_goals="{@todo}" output_goals="{@todo}"/>
          </Sequence>
        </BehaviorTree>
        """,
        todo=[1, 2, 3, 4],
    )
    assert tree.wires == []
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [[2, 3, 4], [2, 3, 4]]
    assert _board(tree)["todo"] == [3, 4]


def test_a_subtree_entry_from_outside_read_by_several_nodes() -> None:
    tree = _load(
        """
        <BehaviorTree ID="Main">
          <Sequence>
            <SubTree ID="Two" g="1;2"/>
            <SubTree ID="Two" name="again" g="{goal}"/>
          </Sequence>
        </BehaviorTree>
        <BehaviorTree ID="Two">
          <Sequence><Seen value="{g}"/><Move goal="{g}"/><Seen name="b" value="{g}"/></Sequence>
        </BehaviorTree>
        """,
        goal=(3, 3),
    )
    assert tree.tick() is State.SUCCEEDED
    assert SEEN == [(1.0, 2.0), (1.0, 2.0), (3.0, 3.0), (3.0, 3.0)]
