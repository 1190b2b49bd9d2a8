"""The ``btcap`` command line: exit codes, messages, and what show/dot print."""

from __future__ import annotations

import argparse
import importlib.metadata
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import btcap
import btcap.cli
from btcap.cli import build_parser, main

EXAMPLES = Path(__file__).resolve().parents[3] / "examples" / "trees"
PATROL = EXAMPLES / "patrol.yaml"

BAD = """\
btcap: 1
root:
  type: ReactiveSequence
  name: root
  children:
    - {type: Wiat, name: pause, options: {seconds: 1}}
"""


@pytest.fixture(autouse=True)
def logging_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[Any, ...]]:
    """Record instead of configuring structlog: global config must not leak across tests."""
    calls: list[tuple[Any, ...]] = []
    monkeypatch.setattr(
        btcap.cli, "configure_logging", lambda level, json=False: calls.append((level, json))
    )
    return calls


@pytest.fixture
def bad_file(tmp_path: Path) -> Path:
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    return path


# -- tree validate --------------------------------------------------------------------
def test_validate_ok_prints_ok_per_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "validate", str(PATROL), str(EXAMPLES / "patrol.json")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [f"{PATROL}: ok", f"{EXAMPLES / 'patrol.json'}: ok"]


def test_validate_bad_file_exits_1_with_the_problems(
    capsys: pytest.CaptureFixture[str], bad_file: Path
) -> None:
    assert main(["tree", "validate", str(PATROL), str(bad_file)]) == 1
    captured = capsys.readouterr()
    assert f"{PATROL}: ok" in captured.out
    assert captured.err.startswith(f"{bad_file}: node 'root/pause' field 'type'")
    assert "did you mean Wait" in captured.err
    assert "Traceback" not in captured.err


def test_validate_missing_file_exits_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, bad_file: Path
) -> None:
    assert main(["tree", "validate", str(tmp_path / "nope.yaml"), str(bad_file)]) == 2
    err = capsys.readouterr().err
    assert f"btcap: error: {tmp_path / 'nope.yaml'}: no such file" in err
    assert f"{bad_file}: node 'root/pause'" in err  # the other files are still checked


# -- tree show ------------------------------------------------------------------------
def test_show_prints_types_names_options_and_wires(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "show", str(PATROL)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Visit two waypoints")  # the description
    assert "tree 'patrol': 8 nodes, 2 wires" in out
    assert "Sequence 'patrol'" in out
    assert "├── Constant 'first'  value=(1.0, 2.0) type=tuple[float, float]" in out
    assert "Timeout 'leg1'  seconds=5.0" in out
    assert "Subtree 'go_first' (tree 'goto')" in out
    assert "in  goal <- patrol/first.value" in out
    assert "Wait 'drive'  seconds=0.5" in out
    assert "[idle]" not in out  # not ticked: no states


def test_show_of_a_ticked_tree_shows_states_and_outputs() -> None:
    tree = btcap.load_tree(PATROL)
    tree.root.setup()
    tree.find("patrol/first").tick()
    text = btcap.render_text(tree)
    assert "Constant 'first'  value=(1.0, 2.0) type=tuple[float, float]  [succeeded]" in text
    assert "out value = (1.0, 2.0)" in text
    assert "Log 'done'  message='patrol finished'  [idle]" in text


def test_show_bad_file_exits_1(capsys: pytest.CaptureFixture[str], bad_file: Path) -> None:
    assert main(["tree", "show", str(bad_file)]) == 1
    assert capsys.readouterr().err.startswith(f"{bad_file}: node 'root/pause' field 'type'")


# -- tree dot -------------------------------------------------------------------------
def _check_dot(text: str, tree: btcap.Tree) -> None:
    assert text.startswith(f'digraph "{tree.name}" {{')
    assert text.rstrip().endswith("}")
    assert text.count("{") == text.count("}")
    for node in tree.nodes():
        assert f'"{node.path}" [label="{type(node).__name__}\\n{node.name}' in text
    for parent in tree.nodes():
        for child in parent.children:
            assert f'"{parent.path}" -> "{child.path}";' in text
    for w in tree.wires:
        edge = f'"{w.source.path}" -> "{w.target.path}" [style=dashed'
        assert edge in text
        assert f'label="{w.source_port} -> {w.target_port}"' in text
    # every statement line ends in ';' or opens/closes a block
    for line in text.splitlines()[1:-1]:
        assert re.search(r"(;|\{)$", line.rstrip()) or line.strip() == "}", line


def test_dot_prints_every_node_child_edge_and_wire(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "dot", str(PATROL)]) == 0
    text = capsys.readouterr().out
    tree = btcap.load_tree(PATROL)
    _check_dot(text, tree)
    # the subtrees are clusters with their own, prefixed nodes
    assert 'subgraph "cluster_patrol/leg1/go_first::"' in text
    assert '"patrol/leg1/go_first::goto/drive" [label="Wait\\ndrive' in text


def test_dot_writes_to_a_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "patrol.dot"
    assert main(["tree", "dot", str(PATROL), "-o", str(out)]) == 0
    assert capsys.readouterr().out == ""
    _check_dot(out.read_text(), btcap.load_tree(PATROL))


def test_dot_escapes_quotes_and_colours_states() -> None:
    tree = btcap.Tree(btcap.Log("say", message='say "hi"', level="debug"))
    tree.tick()
    text = btcap.render_dot(tree)
    assert r"""label="Log\nsay\nmessage='say \"hi\"'\nlevel='debug'\n[succeeded]",""" in text
    assert "fillcolor=palegreen" in text


def test_dot_to_an_unwritable_place_exits_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["tree", "dot", str(PATROL), "-o", str(tmp_path / "no" / "x.dot")]) == 2
    assert "cannot write" in capsys.readouterr().err


# -- tree nodes -----------------------------------------------------------------------
def test_nodes_lists_types_with_ports(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "nodes"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert (
        "Sequence: Succeeds when every child succeeds in order; resumes at the running child."
        in lines
    )
    assert (
        "ReactiveSequence: Succeeds when every child succeeds in order; starts from the first "
        "child every tick." in lines
    )
    assert (
        "Fallback: Succeeds at the first child that succeeds; resumes at the running child."
        in lines
    )
    assert "  option retries: int >= 0 = 1" in out
    assert main(["tree", "nodes", "Wait"]) == 0
    assert capsys.readouterr().out.splitlines()[1] == "  option seconds: float >= 0"


def test_nodes_unknown_type_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "nodes", "Sequnce"]) == 2
    assert "did you mean Sequence" in capsys.readouterr().err


# -- usage ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        ([], "usage: btcap"),
        (["tree"], "usage: btcap tree"),
        (["bogus"], "invalid choice: 'bogus'"),
        (["tree", "show"], "the following arguments are required: FILE"),
        (["tree", "validate"], "the following arguments are required: FILE"),
        (["--log-level", "loud", "tree", "nodes"], "invalid choice: 'loud'"),
        (["tree", "show", "/no/such/tree.yaml"], "btcap: error: /no/such/tree.yaml: no such file"),
        (["tree", "dot", "/"], "is a directory"),
    ],
)
def test_usage_errors_exit_2_without_traceback(
    capsys: pytest.CaptureFixture[str], argv: list[str], needle: str
) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err
    assert "Traceback" not in err


def test_version_and_help_exit_0(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"btcap {btcap.__version__}"
    assert main(["tree", "--help"]) == 0
    assert "validate" in capsys.readouterr().out


def test_log_flags_reach_configure_logging(logging_calls: list[tuple[Any, ...]]) -> None:
    assert main(["--log-level", "debug", "--log-json", "tree", "validate", str(PATROL)]) == 0
    assert logging_calls == [("debug", True)]
    assert main(["tree", "validate", str(PATROL)]) == 0
    assert logging_calls[-1] == ("warning", False)


class _BrokenEntryPoint:
    name = "acme"
    value = "acme_nodes:nodes"

    def load(self) -> Any:
        raise ImportError("No module named 'acme_nodes'")


def test_broken_plugin_is_reported_and_no_plugins_skips_it(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = importlib.metadata.entry_points

    def entry_points(*, group: str) -> Any:
        return [_BrokenEntryPoint()] if group == "btcap.nodes" else real(group=group)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)
    assert main(["tree", "validate", str(PATROL)]) == 1
    assert "node plugin 'acme' (acme_nodes:nodes)" in capsys.readouterr().err
    assert main(["--no-plugins", "tree", "validate", str(PATROL)]) == 0


def test_subcommands_come_from_registered_modules() -> None:
    parser = build_parser()
    actions = [a for a in parser._actions if a.dest == "command"]
    assert actions
    assert "tree" in actions[0].choices  # type: ignore[operator]


def test_python_dash_m_btcap_version() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "btcap", "--version"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == f"btcap {btcap.__version__}"


def test_ctrl_c_while_the_parser_is_built_is_one_line_and_exit_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A KeyboardInterrupt anywhere in the command, even before a handler runs."""

    def interrupted() -> list[str]:
        raise KeyboardInterrupt

    monkeypatch.setattr(btcap.cli, "_command_modules", interrupted)
    assert main(["--help"]) == 130
    assert capsys.readouterr().err == "btcap: interrupted\n"


def _every_parser(
    parser: argparse.ArgumentParser, name: str = "btcap"
) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, subparser in action.choices.items():
                yield from _every_parser(subparser, f"{name} {sub}")


#: reStructuredText a docstring may hold and a terminal shows raw: ``code``, roles
#: (:class:`X`, :func:`~a.b`), directives, links and the literal-block marker.
RST = re.compile(r"``|:[a-z]+:`|^\s*\.\. [a-z-]+::|`_|::$", re.MULTILINE)


def test_the_checker_sees_rest_markup() -> None:
    for text in ("``btcap keys``", "see :class:`Tree`", ":func:`~a.b`", "like so::", ".. note::"):
        assert RST.search(text), text
    assert not RST.search("--monitor [HOST:]PORT: a port 0-65535, e.g. 127.0.0.1:8765")


def test_every_help_is_plain_text() -> None:
    """Help shows in a terminal (and, verbatim, on the CLI reference page)."""
    parsers = list(_every_parser(build_parser()))
    assert len(parsers) > 10
    for name, parser in parsers:
        marked = [line for line in parser.format_help().splitlines() if RST.search(line)]
        assert marked == [], f"{name} --help shows reST markup"
