"""``btcap tree`` on BehaviorTree.CPP files: --main, --stub-missing, --model, --stub-script.

A Nav2 tree validates and dry-runs from its files alone (the Nav2-shaped files of
examples/nav2/ were written for btcap).
"""

from __future__ import annotations

from pathlib import Path

import pytest

import btcap.cli
from btcap.cli import main

NAV2 = Path(__file__).resolve().parents[3] / "examples" / "nav2"
MODEL = NAV2 / "nav2_tree_nodes.xml"
DRY_RUN = NAV2 / "dry_run.xml"
STUBS = ["--stub-missing", "--model", str(MODEL)]


@pytest.fixture(autouse=True)
def _no_logging_config(monkeypatch: pytest.MonkeyPatch) -> None:
    """Global structlog configuration must not leak across tests."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def test_a_nav2_tree_validates_with_stubs_from_its_model(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["tree", "validate", str(DRY_RUN)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 16  # one line per unknown type, and what to do once
    assert err[-1].endswith("and add --stub-missing")
    assert main(["tree", "validate", *STUBS, str(DRY_RUN)]) == 0
    captured = capsys.readouterr()
    assert captured.out == f"{DRY_RUN}: ok\n"
    assert captured.err == ""  # a model file needs no BTCPP_format


def test_a_nav2_tree_dry_runs_as_its_script_says(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["tree", "run", "--fast", *STUBS, str(DRY_RUN)]) == 0
    assert capsys.readouterr().out.endswith("succeeded after 1 tick\n")
    script = tmp_path / "stubs.yaml"
    script.write_text(
        "types:\n  ComputePathToPose: [RUNNING, SUCCESS]\n"
        "names:\n  FollowPath: FAILURE\n  GoalUpdated: FAILURE\n"
    )
    args = ["tree", "run", "--fast", *STUBS, "--stub-script", str(script), str(DRY_RUN)]
    assert main(args) == 1
    out = capsys.readouterr().out
    # Nav2's RecoveryNode: FollowPath's own recovery, then the navigator's in turn, until
    # its RoundRobin (wrap_around false by default) has none left.
    assert "RecoveryNode 'NavigateRecovery'  [failed]" in out
    assert "RoundRobin 'RecoveryActions'  [failed]" in out
    assert out.endswith("failed after 5 ticks\n")


def test_main_picks_the_tree_to_run(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    path = tmp_path / "two.xml"
    path.write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="A"><AlwaysSuccess/></BehaviorTree>'
        '<BehaviorTree ID="B"><AlwaysFailure/></BehaviorTree></root>'
    )
    assert main(["tree", "validate", str(path)]) == 1
    assert "(A, B); say which one to run (--main TREE" in capsys.readouterr().err
    assert main(["tree", "run", "--fast", "--main", "B", str(path)]) == 1
    assert capsys.readouterr().out.endswith("failed after 1 tick\n")


def test_what_behaviortree_cpp_warns_about_is_one_warning_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    path = tmp_path / "old.xml"
    path.write_text("<root><BehaviorTree><AlwaysSuccess/></BehaviorTree></root>")
    assert main(["tree", "validate", str(path)]) == 0
    assert capsys.readouterr().err == (
        f"warning: {path}: line 1: <root> has no BTCPP_format; read as format 4 "
        f'(BehaviorTree.CPP warns too): add BTCPP_format="4"\n'
    )


@pytest.mark.parametrize("option", ["--model", "--stub-script"])
def test_missing_model_or_script_files_are_usage_errors(
    capsys: pytest.CaptureFixture[str], option: str
) -> None:
    assert main(["tree", "validate", option, "nope.xml", str(DRY_RUN)]) == 2
    assert "nope.xml: no such file" in capsys.readouterr().err
