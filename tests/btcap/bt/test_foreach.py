"""ParallelForEach: a lane per item of a growing list, at most N at once, halted properly.

Every tick goes through ``tick_checked`` (the halting invariant).
"""

from __future__ import annotations

from typing import Any, ClassVar

import anyio
import pytest

from btcap import (
    Leaf,
    Node,
    ParallelForEach,
    Port,
    ReactiveSequence,
    State,
    Tree,
    TreeError,
    loads_tree,
)
from btcap.actors import ManualClock
from btcap.bt.invariants import tick_checked as tick
from btcap.bt.registry import default_registry

S, F, R = State.SUCCEEDED, State.FAILED, State.RUNNING


class Source(Leaf):
    """Outputs the list ``items`` (settable) and whether it is ``complete``; RUNNING."""

    OUTPUTS: ClassVar[Any] = {"items": list[int], "complete": bool}

    def __init__(self, name: str = "source") -> None:
        super().__init__(name)
        self.items: list[int] = []
        self.complete = False

    def on_tick(self) -> State:
        self.outputs["items"] = list(self.items)
        self.outputs["complete"] = self.complete
        return R


class Lane(Leaf):
    """Works on ``item`` for ``item % 10`` ticks (0: done at once); fails items in
    ``failing``; logs every start, tick and untick in ``log``."""

    INPUTS: ClassVar[Any] = {"item": Port(int)}

    def __init__(self, name: str, log: list[tuple[str, int]], failing: set[int]) -> None:
        super().__init__(name)
        self.log, self.failing, self.left = log, failing, -1

    def on_tick(self) -> State:
        item = self.inputs["item"]
        if self.left < 0:
            self.left = item % 10
            self.log.append(("start", item))
        self.log.append(("tick", item))
        if self.left == 0:
            return F if item in self.failing else S
        self.left -= 1
        return R

    def on_untick(self) -> None:
        self.log.append(("untick", self.inputs["item"]))

    def on_reset(self) -> None:
        self.left = -1


def build(
    n: int, lanes: int = 0, *, retry: bool = False, failing: set[int] | None = None
) -> tuple[Tree, Source, ParallelForEach, list[tuple[str, int]]]:
    log: list[tuple[str, int]] = []
    bad = failing or set()
    source = Source()
    each = ParallelForEach(
        "each",
        children=[Lane(f"lane{i}", log, bad) for i in range(n)],
        max_concurrency=lanes,
        retry_failed=retry,
    )
    tree = Tree(ReactiveSequence("root", children=[_Always(source), each]))
    tree.wire(source, "items", each, "items")
    tree.wire(source, "complete", each, "complete")
    return tree, source, each, log


class _Always(Node):
    """Ticks its one child and succeeds while it runs (keeps the source beside the loop)."""

    MIN_CHILDREN = MAX_CHILDREN = 1

    def __init__(self, child: Node) -> None:
        super().__init__(f"always_{child.name}", children=[child])

    def on_tick(self) -> State:
        self.children[0].tick()
        self.children[0].untick()
        return S


def running(each: ParallelForEach) -> list[int]:
    return [c.inputs["item"] for c in each.children if c.state is R]


def test_a_growing_list_runs_each_item_once_at_most_n_at_once() -> None:
    tree, source, each, log = build(4, lanes=2)
    source.items = [13, 2]
    assert tick(tree) is R
    assert sorted(running(each)) == [2, 13]
    source.items = [13, 2, 4, 21, 0]  # grows while the first two run
    peak = 0
    for _ in range(40):
        state = tick(tree)
        peak = max(peak, len(running(each)))
        if state is not R:
            break
        if ("start", 21) in log and 7 not in source.items:
            source.items.append(7)  # and again, later
            source.complete = True
    assert state is S
    assert peak == 2  # never more than max_concurrency, though 4 lanes exist
    starts = [item for what, item in log if what == "start"]
    assert sorted(starts) == [0, 2, 4, 7, 13, 21]  # each exactly once
    assert starts.index(4) < starts.index(21) < starts.index(0)  # in the list's order
    assert (each.outputs["succeeded"], each.outputs["failed"]) == (6, 0)


def test_it_waits_for_complete_and_for_items_that_come_later() -> None:
    tree, source, each, _ = build(2)
    for _ in range(3):
        assert tick(tree) is R  # an empty list that may still grow
    source.items = [1]
    assert tick(tree) is R
    assert running(each) == [1]
    assert tick(tree) is R  # item 1 done, but the list is not complete
    source.complete = True
    assert tick(tree) is S


def test_halting_the_node_halts_its_lanes_and_they_resume() -> None:
    tree, source, each, log = build(3)
    source.items = [5, 6]
    tick(tree)
    tree.untick()
    assert sorted(i for what, i in log if what == "untick") == [5, 6]
    assert all(c.state in (State.PAUSED, State.IDLE) for c in each.children)
    tick(tree)  # resumes: no item starts a second time
    assert [i for what, i in log if what == "start"] == [5, 6]


def test_a_parent_giving_up_halts_the_running_lanes() -> None:
    log: list[tuple[str, int]] = []
    source = Source()
    each = ParallelForEach("each", children=[Lane(f"l{i}", log, set()) for i in range(2)])
    gate = _Gate("gate")
    tree = Tree(ReactiveSequence("root", children=[gate, _Always(source), each]))
    tree.wire(source, "items", each, "items")
    source.items = [8, 9]
    assert tick(tree) is R
    gate.ok = False
    assert tick(tree) is F  # tick_checked: no lane left running unticked
    assert sorted(i for what, i in log if what == "untick") == [8, 9]


class _Gate(Leaf):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.ok = True

    def on_tick(self) -> State:
        return S if self.ok else F


def test_failed_items_fail_the_node_or_run_again_with_retry() -> None:
    tree, source, each, log = build(2, failing={3})
    source.items, source.complete = [3, 1], True
    while (state := tick(tree)) is R:
        pass
    assert state is F
    assert (each.outputs["failed"], each.outputs["succeeded"]) == (1, 1)

    tree, source, each, log = build(2, retry=True, failing={3})
    source.items, source.complete = [3, 1], True
    for _ in range(12):
        tick(tree)
    assert [i for what, i in log if what == "start"].count(3) >= 3  # while it is listed
    each.children[0].failing.clear()  # type: ignore[attr-defined]
    each.children[1].failing.clear()  # type: ignore[attr-defined]
    while (state := tick(tree)) is R:
        pass
    assert state is S


class FailsOnce(Leaf):
    """Fails its first item, succeeds after; logs every value it is ticked with."""

    INPUTS: ClassVar[Any] = {"item": Port(tuple[int, int])}

    def __init__(self, name: str, seen: list[tuple[int, int]]) -> None:
        super().__init__(name)
        self.seen = seen

    def on_tick(self) -> State:
        self.seen.append(self.inputs["item"])
        return F if len(self.seen) == 1 else S


async def test_a_failed_item_waits_retry_after_s_and_runs_again_from_its_latest_value() -> None:
    # An object dropped where its carrier failed: the list read in the tick of the
    # failure may still say where it was taken, so it runs again only from a later one.
    with anyio.fail_after(5):
        clock = ManualClock()
        seen: list[tuple[int, int]] = []
        lane = FailsOnce("a", seen)
        each = ParallelForEach(
            "each",
            children=[lane],
            key=0,
            retry_failed=True,
            retry_after_s=1.0,
            inputs={"items": [(7, 0)], "complete": True},
        )
        tree = Tree(each, clock=clock)
        assert tick(tree) is R  # started, failed: waits, the node with it
        assert seen == [(7, 0)]
        each.set_input("items", [(7, 1)])  # the list now says where the object lies
        await clock.advance(0.9)
        assert tick(tree) is R
        assert seen == [(7, 0)]  # not yet
        await clock.advance(0.1)
        assert tick(tree) is S
        assert seen == [(7, 0), (7, 1)]  # again, from where it lies now


def test_started_again_after_its_result_it_forgets_the_items_done() -> None:
    tree, source, _, log = build(1)
    source.items, source.complete = [0], True
    assert tick(tree) is S
    assert tick(tree) is S
    assert [i for what, i in log if what == "start"] == [0, 0]


def test_items_are_checked_against_the_lane_input_type() -> None:
    tree, source, each, _ = build(1)
    source.complete = True
    source.items = ["x"]  # type: ignore[list-item]
    tick(tree)
    assert each.state is State.ERROR
    assert "lane0.item: expected int" in str(each.error)


def test_bad_configurations_are_refused_when_the_tree_is_validated() -> None:
    log: list[tuple[str, int]] = []
    too_wide = ParallelForEach("w", children=[Lane("l", log, set())], max_concurrency=2)
    with pytest.raises(TreeError, match="max_concurrency 2 with 1 children"):
        Tree(too_wide, name="t").validate(provided=[(too_wide, "items")])
    no_item = ParallelForEach("n", children=[_Gate("g")])
    with pytest.raises(TreeError, match="has no input 'item'"):
        Tree(no_item, name="t").validate(provided=[(no_item, "items")])


LANES_YAML = """
btcap: 1
root:
  type: ParallelForEach
  name: each
  options: {max_concurrency: 2}
  inputs: {items: [4, 5, 6]}
  children:
    - {type: Subtree, name: a, options: {tree: lane}}
    - {type: Subtree, name: b, options: {tree: lane}}
    - {type: Subtree, name: c, options: {tree: lane}}
subtrees:
  lane:
    root: {type: Compare, name: cmp, options: {op: ">"}, inputs: {b: 3}}
    public: {inputs: {item: cmp.a}}
"""


def test_a_tree_file_builds_lanes_from_one_subtree() -> None:
    tree = loads_tree(LANES_YAML)
    each = tree.root
    assert isinstance(each, ParallelForEach)
    assert tick(tree) is S
    assert each.outputs["succeeded"] == 3


class Pair(Leaf):
    """Runs while its item's second element is 0; logs every value it is ticked with."""

    INPUTS: ClassVar[Any] = {"item": Port(tuple[int, int])}

    def __init__(self, name: str, seen: list[tuple[int, int]]) -> None:
        super().__init__(name)
        self.seen = seen

    def on_tick(self) -> State:
        self.seen.append(self.inputs["item"])
        return R if self.inputs["item"][1] == 0 else S


def test_with_a_key_a_changed_item_updates_its_running_lane_instead_of_a_second() -> None:
    seen: list[tuple[int, int]] = []
    each = ParallelForEach(
        "each", children=[Pair("a", seen), Pair("b", seen)], key=0, inputs={"items": [(7, 0)]}
    )
    tree = Tree(each)
    assert tick(tree) is R
    assert seen == [(7, 0)]
    each.set_input("items", [(7, 0), (7, 1)])  # the same item, changed: no second lane
    assert tick(tree) is S
    assert seen == [(7, 0), (7, 1)]
    each.set_input("items", [5])
    each.reset()
    with pytest.raises(TreeError, match="has no hashable element 0"):
        each.on_tick()


class Taken(Leaf):
    """Records its item and succeeds (a lane in an XML file)."""

    INPUTS: ClassVar[Any] = {"item": Port(int)}
    seen: ClassVar[list[int]] = []

    def on_tick(self) -> State:
        Taken.seen.append(self.inputs["item"])
        return S


def test_behaviortree_cpp_xml_spells_it_with_the_btcap_prefix_and_feeds_it_an_entry() -> None:
    registry = default_registry(plugins=False)
    registry.register(Taken)
    xml = """<root BTCPP_format="4" main_tree_to_execute="M"><BehaviorTree ID="M">
      <btcap.ParallelForEach items="{todo}" complete="{no_more}" max_concurrency="1">
        <Taken/><Taken/>
      </btcap.ParallelForEach></BehaviorTree></root>"""
    tree = loads_tree(xml, "xml", registry)
    assert tree.blackboard is not None
    tree.blackboard["todo"], tree.blackboard["no_more"] = [3], False
    Taken.seen.clear()
    assert tick(tree) is R
    tree.blackboard["todo"], tree.blackboard["no_more"] = [3, 4, 5], True  # it grew
    assert tick(tree) is S  # one at a time: a lane done at once takes the next item
    assert Taken.seen == [3, 4, 5]


class _Chooses(ParallelForEach):
    """Free lanes take the largest items first; items in ``held`` wait."""

    held: ClassVar[set[int]] = set()

    def order(self, items: list[Any]) -> list[Any]:
        return sorted((i for i in items if i not in self.held), reverse=True)


def test_a_subclass_chooses_which_item_a_free_lane_takes_and_what_waits() -> None:
    log: list[tuple[str, int]] = []
    source = Source()
    each = _Chooses("each", children=[Lane(f"lane{i}", log, set()) for i in range(2)])
    tree = Tree(ReactiveSequence("root", children=[_Always(source), each]))
    tree.wire(source, "items", each, "items")
    tree.wire(source, "complete", each, "complete")
    _Chooses.held = {3}
    source.items, source.complete = [1, 2, 3, 4], True
    assert tick(tree) is R
    assert sorted(running(each)) == [2, 4]  # not the first two listed
    for _ in range(10):
        assert tick(tree) is R  # 3 is held back: waiting, so the node is not done
    assert [item for what, item in log if what == "start"] == [4, 2, 1]
    _Chooses.held = set()
    for _ in range(10):
        if tick(tree) is S:
            break
    assert [item for what, item in log if what == "start"] == [4, 2, 1, 3]
