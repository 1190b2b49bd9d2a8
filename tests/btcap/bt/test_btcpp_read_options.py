"""Built-in options read from the blackboard (``num_attempts="{n}"``), against
BehaviorTree.CPP 4.8 (behaviortreepy) tick by tick, and on btcap's clock for durations."""

from __future__ import annotations

import random

import anyio
import pytest

pytest.importorskip(
    "behaviortreepy",
    reason="behaviortreepy (BehaviorTree.CPP 4.8) has wheels only for CPython 3.11 on x86-64 Linux",
)

from btcpp_oracle import El, compare, random_tree

from btcap import State, Tree
from btcap.actors import ManualClock
from btcap.bt.files import loads_tree
from btcap.bt.registry import default_registry


def _counted(rng: random.Random, k: int) -> El:
    """Repeat/Retry with counts from entries a Script sets, around random subtrees; a
    child Script may change the count between attempts."""
    n, c = rng.choice((-2, -1, 0, 1, 2, 3)), rng.choice((-2, -1, 0, 1, 2))
    inner = random_tree(rng, max_depth=2)
    if rng.random() < 0.5:  # a child that never runs (see read_options: a running child)
        step = rng.choice(("n := n - 1", "n := n + 1", "n := 1"))
        leaf = El("Cond", f"a{k}", script="".join(rng.choice("SFF") for _ in range(3)))
        inner = El("Sequence", f"s{k}", children=[El("Script", f"c{k}", {"code": step}), leaf])
    retry = El("RetryUntilSuccessful", f"r{k}", {"num_attempts": "{n}"}, [inner])
    repeat = El("Repeat", f"p{k}", {"num_cycles": "{k}"}, [retry])
    setup = El("Script", f"set{k}", {"code": f"n := {n}; k := {c}"})
    return El("Sequence", f"top{k}", children=[setup, repeat])


@pytest.mark.filterwarnings("ignore::btcap.bt.state.RestartLoopWarning")
@pytest.mark.parametrize("once", [False, True], ids=["tickExactlyOnce", "tickOnce"])
def test_counts_from_entries_agree_with_behaviortree_cpp(once: bool) -> None:
    """Read on every tick, and a retry's again after a failed attempt, as BT.CPP 4.8."""
    rng = random.Random(31)
    exact = 0
    for k in range(150):
        outcome = compare(_counted(rng, k), ticks=8, once=once)
        assert outcome.mismatch is None, outcome.mismatch
        exact += outcome.ticks
    assert exact > 400  # most ticks compared exactly, not cut short by a difference


def test_a_retry_reads_the_count_its_child_just_wrote() -> None:
    """BT.CPP re-reads num_attempts after a failed attempt: here the second attempt
    lowers it to 1, so the retry gives up at once (it would try again on the old 5)."""
    child = El("Sequence", "s", children=[El("Script", "c", {"code": "n := n - 2"})])
    child.children.append(El("Cond", "a", script="F"))
    retry = El("RetryUntilSuccessful", "r", {"num_attempts": "{n}"}, [child])
    root = El("Sequence", "top", children=[El("Script", "set", {"code": "n := 5"}), retry])
    outcome = compare(root, ticks=4)
    assert outcome.mismatch is None, outcome
    assert outcome.stopped_by is None, outcome


def _clocked(xml: str, entries: dict[str, int]) -> tuple[ManualClock, Tree]:
    clock = ManualClock()
    tree = loads_tree(xml, "xml", default_registry(plugins=False), clock=clock, entries=entries)
    return clock, tree


_TIMED = """<root BTCPP_format="4"><BehaviorTree ID="Main">
  <Sequence><Sleep msec="{t}"/><Timeout msec="{limit}"><Sleep msec="{t}"/></Timeout>
  <Delay delay_msec="{t}"><AlwaysSuccess/></Delay></Sequence>
</BehaviorTree></root>"""


async def test_durations_from_entries_are_read_when_the_node_starts() -> None:
    """Sleep/Timeout/Delay read msec when they start (BT.CPP's onStart / timer start):
    a new value changes the next run, not the one under way; Timeout msec=0 is no limit."""
    with anyio.fail_after(5):
        clock, tree = _clocked(_TIMED, {"t": 100, "limit": 0})
        assert tree.blackboard is not None
        states = [tree.tick()]  # the first Sleep starts: 100 ms
        tree.blackboard["t"] = 10_000
        await clock.advance(0.1)
        states.append(tree.tick())  # it is done; the second starts: 10 s (no time limit)
        tree.blackboard["t"] = 0
        await clock.advance(0.1)
        states.append(tree.tick())  # still 10 s
        await clock.advance(10)
        states.append(tree.tick())  # done; the Delay starts: 0 ms
        assert states == [State.RUNNING] * 3 + [State.SUCCEEDED]


async def test_a_timeout_from_an_entry_times_out() -> None:
    with anyio.fail_after(5):
        clock, tree = _clocked(_TIMED, {"t": 100, "limit": 50})
        assert tree.tick() is State.RUNNING
        await clock.advance(0.1)
        assert tree.tick() is State.RUNNING  # the first Sleep done, the second started
        await clock.advance(0.05)
        assert tree.tick() is State.FAILED  # 50 ms: timed out
