"""The ``.btlog`` file itself: written as the run goes, readable when cut short, refused
with a clear line when it is not one."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest

from btcap import AlwaysFailure, AlwaysSuccess, Fallback, Inverter, Sequence, State, Tree
from btcap.actors import ManualClock
from btcap.bt.files.btcpp_status import FAILURE, IDLE, RUNNING, SUCCESS
from btcap.bt.files.btlog import HEADER, BtlogError, BtlogRecorder, read_btlog
from btcap.bt.leaves import Wait


def _tree(clock: ManualClock | None = None) -> Tree:
    return Tree(
        Sequence(
            "root",
            children=[
                Wait("wait", seconds=0.2),
                Fallback("fb", children=[AlwaysFailure("no"), AlwaysSuccess("yes")]),
                Inverter("inv", children=[AlwaysFailure("fails")]),
            ],
        ),
        name="demo",
        clock=clock or ManualClock(),
    )


def test_each_tick_is_on_disk_before_the_run_ends(tmp_path: Path) -> None:
    """flush_s=0: every tick is written at once, so a killed run keeps what it did."""
    tree = _tree()
    path = tmp_path / "run.btlog"
    rec = BtlogRecorder(tree, path, flush_s=0)
    assert tree.tick() is State.RUNNING
    first = read_btlog(path)
    assert [(u, s) for _, u, s in first.transitions] == [(1, RUNNING), (2, RUNNING)]
    assert '<Sleep name="wait" _uid="2" msec="200"/>' in first.xml
    rec.close()
    assert "tick" not in tree.__dict__  # the tree is left as it was


async def test_a_file_cut_inside_a_record_reads_up_to_the_last_whole_one(tmp_path: Path) -> None:
    clock = ManualClock()
    tree = _tree(clock)
    path = tmp_path / "run.btlog"
    with anyio.fail_after(5), BtlogRecorder(tree, path):
        assert tree.tick() is State.RUNNING
        await clock.advance(0.25)
        assert tree.tick() is State.SUCCEEDED
    whole = read_btlog(path)
    # times are the tree's clock: the wait ended 0.25 s (virtual) after the start
    assert [t for t, u, s in whole.transitions if (u, s) == (2, SUCCESS)] == [250_000]
    assert not whole.partial
    # the root's result, then BehaviorTree.CPP's tree resets it
    assert [(u, s) for _, u, s in whole.transitions[-2:]] == [(1, SUCCESS), (1, IDLE)]
    assert (4, FAILURE) in [(u, s) for _, u, s in whole.transitions]
    cut = tmp_path / "cut.btlog"
    cut.write_bytes(path.read_bytes()[:-4])
    short = read_btlog(cut)
    assert short.partial
    assert short.transitions == whole.transitions[:-1]


def test_not_a_btlog_is_refused_with_the_file_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.btlog"
    bad.write_bytes(b"hello")
    with pytest.raises(BtlogError, match=r"bad\.btlog: expected a \.btlog starting with"):
        read_btlog(bad)
    bad.write_bytes(HEADER + (1000).to_bytes(4, "little") + b"<root/>")
    with pytest.raises(BtlogError, match="ends inside the tree's XML"):
        read_btlog(bad)
    with pytest.raises(
        BtlogError, match=r"run\.log: a tree log for Groot2 must be named \*\.btlog"
    ):
        BtlogRecorder(_tree(), tmp_path / "run.log")
