"""``btcap tree show|dot|run`` say what a BehaviorTree.CPP tree does with its blackboard:
each node's entry ports, the entries to set before ticking, and in a dry run each one
read before anything set it."""

from __future__ import annotations

from pathlib import Path

import pytest

import btcap.cli
from btcap.cli import main

TREE = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <Sequence>
      <Plan goal="{goal}" path="{path}"/>
      <Follow path="{path}"/>
      <Script code="tries := 2"/>
      <SubTree ID="Nav" target="{path}"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="Nav">
    <Sequence>
      <Follow path="{target}"/>
      <Follow path="{goals}"/>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel>
    <Action ID="Plan"><input_port name="goal"/><output_port name="path"/></Action>
    <Action ID="Follow"><input_port name="path"/></Action>
  </TreeNodesModel>
</root>
"""


@pytest.fixture(autouse=True)
def _no_logging_config(monkeypatch: pytest.MonkeyPatch) -> None:
    """Global structlog configuration must not leak across tests."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    path = tmp_path / "nav.xml"
    path.write_text(TREE)
    return path


def test_show_lists_entry_ports_and_the_entries_to_set(
    capsys: pytest.CaptureFixture[str], tree: Path
) -> None:
    assert main(["tree", "show", "--stub-missing", str(tree)]) == 0
    out = capsys.readouterr().out
    plan = "├── Plan 'Plan'\n│       · in  goal <- {goal}\n│       · out path -> {path}\n"
    assert plan in out
    assert "· in  path <- {path} (wire from Sequence/Plan.path)" in out
    assert "· script writes {tries}" in out
    assert "· in  path <- {goals}" in out  # inside the subtree
    assert out.endswith(
        "blackboard entries to set before ticking (read before any node writes them):\n"
        "  {goal}: read by Sequence/Plan (goal) before any node writes it (line 4)\n"
        "blackboard entries nobody sets (a subtree reads them, its SubTree passes none):\n"
        "  {goals}: read by Sequence/Follow_2 (path) in tree 'Nav' before any node writes "
        "it, and <SubTree ID='Nav'> at line 7 does not pass it in (goals=\"{...}\" or "
        "_autoremap) (line 13)\n"
    )


def test_dot_labels_entry_ports_and_notes_the_entries_to_set(
    capsys: pytest.CaptureFixture[str], tree: Path
) -> None:
    assert main(["tree", "dot", "--stub-missing", str(tree)]) == 0
    out = capsys.readouterr().out
    assert '"Sequence/Plan" [label="Plan\\nPlan\\nin  goal <- {goal}\\nout path -> {path}"' in out
    note = '"note" [shape=note, label="blackboard entries read before any node writes them:'
    assert note + "\\n{goal}: read by Sequence/Plan (goal) before any node writes it" in out


def test_a_dry_run_names_each_entry_read_before_anything_set_it(
    capsys: pytest.CaptureFixture[str], tree: Path
) -> None:
    assert main(["tree", "run", "--fast", "--stub-missing", str(tree)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"{tree}: line 4: {{goal}}: read by Sequence/Plan (goal) before any node writes it "
        "and it was not set (--set goal=VALUE)",
        f"{tree}: line 13: {{goals}}: read by Sequence/Follow_2 (path) in tree 'Nav' before "
        "any node writes it, and <SubTree ID='Nav'> at line 7 does not pass it in "
        '(goals="{...}" or _autoremap)',
    ]
    assert main(["tree", "run", "--fast", "--stub-missing", "--set", "goal=1", str(tree)]) == 0
    assert "{goal}" not in capsys.readouterr().err  # set: nothing to say
