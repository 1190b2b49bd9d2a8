"""``btcap tree run --btlog``: the run as BehaviorTree.CPP's FileLogger logs the same XML
run by ``tickWhileRunning`` (behaviortreepy), status changes equal."""

from __future__ import annotations

from pathlib import Path

import pytest

from btcap.bt.files.btlog import read_btlog
from btcap.cli import main

XML = """<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">
<Sequence name="root"><Repeat num_cycles="3"><Inverter><AlwaysFailure/></Inverter></Repeat>
<SubTree ID="Pick"/></Sequence></BehaviorTree>
<BehaviorTree ID="Pick"><Fallback><AlwaysFailure/><AlwaysSuccess name="yes"/></Fallback>
</BehaviorTree></root>"""


def test_run_writes_the_log_behaviortree_cpp_writes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bt = pytest.importorskip("behaviortreepy", reason="BehaviorTree.CPP 4.8 bindings")
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "bt"))
    from btlog_pair import changes, elements, settled

    tree = tmp_path / "tree.xml"
    tree.write_text(XML)
    ours, theirs = tmp_path / "btcap.btlog", tmp_path / "btcpp.btlog"
    assert main(["tree", "run", "--fast", "--btlog", str(ours), str(tree)]) == 0
    cpp = bt.BehaviorTreeFactory().create_tree_from_text(XML)
    logger = bt.FileLogger(cpp, str(theirs))
    assert cpp.tick_while_running(0) == bt.NodeStatus.SUCCESS
    settled([(ours, theirs)])
    del logger
    mine, want = read_btlog(ours), read_btlog(theirs)
    assert elements(mine.xml) == elements(want.xml)
    assert changes(mine) == changes(want)
    assert len(changes(mine)) > 20


def test_run_refuses_a_log_not_named_btlog(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tree = tmp_path / "tree.xml"
    tree.write_text(XML)
    assert main(["tree", "run", "--fast", "--btlog", str(tmp_path / "x.log"), str(tree)]) == 2
    assert "--btlog" in capsys.readouterr().err
