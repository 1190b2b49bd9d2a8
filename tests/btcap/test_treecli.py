"""``btcap tree``: your own node types and interfaces, ``run``, and pictures via Graphviz."""

from __future__ import annotations

import shutil
import sys
import textwrap
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

import btcap.cli
from btcap.bt.files import dumps_tree, load_tree
from btcap.cli import main

ROOT = Path(__file__).resolve().parents[2]
CAPS = ROOT / "examples" / "capabilities"
PATROL_XML = ROOT / "examples" / "trees" / "patrol.xml"

NODES = '''\
from btcap import Leaf, State, CapabilityInterface, Port


class Beep(Leaf):
    """Beeps (a test node from a user module)."""

    INPUTS = {"times": Port(int, 1)}

    def on_tick(self) -> State:
        return State.SUCCEEDED


class _Hidden(Leaf):
    def on_tick(self) -> State:
        return State.SUCCEEDED


DOCK = CapabilityInterface("Dock", inputs={"station": str})


def more():
    class Boop(Leaf):
        def on_tick(self) -> State:
            return State.FAILED

    return [Boop]


def clash():
    class Log(Leaf):
        def on_tick(self) -> State:
            return State.SUCCEEDED

    return [Log]
'''

BEEP_XML = """\
<root BTCPP_format="4">
  <BehaviorTree ID="Main">
    <Sequence>
      <Beep times="3"/>
      <DockInputs station="{s}"/>
      <Log message="docking" value="{s}"/>
    </Sequence>
  </BehaviorTree>
</root>
"""


@pytest.fixture(autouse=True)
def _no_logging_config(monkeypatch: pytest.MonkeyPatch) -> None:
    """Global structlog configuration must not leak across tests."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


@pytest.fixture
def user_module(tmp_path: Path) -> Iterator[Path]:
    """A module of the user's own nodes, under a name no other test uses."""
    path = tmp_path / f"user_nodes_{uuid.uuid4().hex[:8]}.py"
    path.write_text(NODES)
    yield path
    sys.modules.pop(path.stem, None)


def _tree(tmp_path: Path, text: str, name: str = "t.xml") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


# -- node types -----------------------------------------------------------------------
def test_validate_implementation_tree_needs_its_interfaces(
    capsys: pytest.CaptureFixture[str],
) -> None:
    impl = CAPS / "greet_impl.yaml"
    assert main(["tree", "validate", str(impl)]) == 1
    err = capsys.readouterr().err
    assert "unknown node type 'GreetInputs'" in err
    assert f"hint: 'GreetInputs' comes from capability interface 'Greet' in {CAPS}" in err
    args = ["tree", "validate", "--interfaces", str(CAPS / "interfaces.yaml")]
    assert main([*args, str(impl), str(CAPS / "greet_impl.xml")]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"{impl}: ok",
        f"{CAPS / 'greet_impl.xml'}: ok",
    ]


def test_missing_interfaces_file_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tree", "show", "--interfaces", "nope.yaml", str(PATROL_XML)]) == 2
    assert "--interfaces nope.yaml: no such file" in capsys.readouterr().err


def test_load_registers_a_modules_nodes_and_interfaces(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, user_module: Path
) -> None:
    tree = _tree(tmp_path, BEEP_XML)
    assert main(["tree", "validate", str(tree)]) == 1
    capsys.readouterr()
    assert main(["tree", "show", "--load", str(user_module), str(tree)]) == 0
    out = capsys.readouterr().out
    assert "Beep 'Beep'" in out
    assert "DockInputs 'DockInputs'" in out
    assert "in  value <- Sequence/DockInputs.station" in out


def test_load_by_dotted_name_and_by_name_in_module(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, user_module: Path
) -> None:
    monkeypatch.chdir(user_module.parent)
    mod = user_module.stem
    assert main(["tree", "nodes", "--load", mod, "Beep"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "Beep: Beeps (a test node from a user module).",
        "  input times: int = 1",
    ]
    assert main(["tree", "nodes", "--load", f"{mod}:more", "Boop"]) == 0
    assert main(["tree", "nodes", "--load", f"{mod}:clash"]) == 2
    assert "is named like the node type 'Log' files already use" in capsys.readouterr().err
    assert main(["tree", "nodes", "--load", mod, "_Hidden"]) == 2
    assert "unknown node type '_Hidden'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("ref", "message"),
    [
        ("no_such_module_here", "--load no_such_module_here: import failed: ModuleNotFoundError"),
        ("missing.py", "--load missing.py: no such file"),
        ("json:nothing", "--load json:nothing: module 'json' has no 'nothing'"),
        ("json:JSONDecodeError", "is neither a Node class nor an interface"),
        ("json:__all__", "expected a Node class, an interface or a function"),
        ("json:loads", "--load json:loads: TypeError"),
    ],
)
def test_bad_load_is_a_usage_error(
    capsys: pytest.CaptureFixture[str], ref: str, message: str
) -> None:
    assert main(["tree", "validate", "--load", ref, str(PATROL_XML)]) == 2
    assert message in capsys.readouterr().err


# -- run ------------------------------------------------------------------------------
def test_run_ticks_the_patrol_to_success_in_virtual_time(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["tree", "run", "--fast", str(PATROL_XML)]) == 0
    out = capsys.readouterr().out
    assert "Log 'done'  message='patrol finished'  [succeeded]" in out
    assert out.splitlines()[-1] == "succeeded after 12 ticks"  # 2 legs of 0.5 s at 10 Hz


@pytest.mark.parametrize(
    ("body", "args", "code", "last"),
    [
        ("<AlwaysFailure/>", [], 1, "failed after 1 tick"),
        ('<Sleep msec="60000"/>', ["--fast", "--max-ticks", "3"], 3, "running after 3 ticks"),
        ("<AlwaysSuccess/>", ["--rate", "1000"], 0, "succeeded after 1 tick"),
    ],
)
def test_run_exit_code_says_how_it_ended(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    body: str,
    args: list[str],
    code: int,
    last: str,
) -> None:
    xml = f'<root BTCPP_format="4"><BehaviorTree ID="M">{body}</BehaviorTree></root>'
    assert main(["tree", "run", *args, str(_tree(tmp_path, xml))]) == code
    assert capsys.readouterr().out.splitlines()[-1] == last


def test_run_refuses_capabilities_which_need_a_team(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    xml = _tree(
        tmp_path,
        """\
        <root BTCPP_format="4" main_tree_to_execute="M">
          <BehaviorTree ID="M"><SubTree ID="Inner"/></BehaviorTree>
          <BehaviorTree ID="Inner"><Greet who="world"/></BehaviorTree>
        </root>
        """,
    )
    args = ["--interfaces", str(CAPS / "interfaces.yaml"), str(xml)]
    assert main(["tree", "validate", *args]) == 0
    assert main(["tree", "run", *args]) == 2
    assert "capability nodes (Greet) are run by a team" in capsys.readouterr().err


@pytest.mark.parametrize("args", [["--rate", "0"], ["--max-ticks", "0"]])
def test_run_refuses_bad_limits(capsys: pytest.CaptureFixture[str], args: list[str]) -> None:
    assert main(["tree", "run", *args, str(PATROL_XML)]) == 2
    assert "btcap: error: --" in capsys.readouterr().err


# -- pictures -------------------------------------------------------------------------
def test_dot_without_graphviz_says_what_to_install(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(shutil, "which", lambda name: None)
    out = tmp_path / "patrol.svg"
    assert main(["tree", "dot", str(PATROL_XML), "-o", str(out)]) == 2
    assert "needs Graphviz's 'dot' program, which is not on PATH" in capsys.readouterr().err
    assert not out.exists()
    assert main(["tree", "dot", str(PATROL_XML), "-o", str(tmp_path / "patrol.dot")]) == 0
    assert (tmp_path / "patrol.dot").read_text().startswith('digraph "Patrol" {')


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz 'dot' is not installed")
@pytest.mark.parametrize(("suffix", "magic"), [(".svg", b"<svg"), (".png", b"\x89PNG")])
def test_dot_renders_pictures_with_graphviz(tmp_path: Path, suffix: str, magic: bytes) -> None:
    out = tmp_path / f"patrol{suffix}"
    assert main(["tree", "dot", str(PATROL_XML), "-o", str(out)]) == 0
    assert magic in out.read_bytes()[:400]


def test_show_of_xml_and_of_its_yaml_dump_agree(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    dumped = tmp_path / "patrol.yaml"
    dumped.write_text(dumps_tree(load_tree(PATROL_XML)))
    assert main(["tree", "show", str(PATROL_XML)]) == 0
    from_xml = capsys.readouterr().out
    assert main(["tree", "show", str(dumped)]) == 0
    assert capsys.readouterr().out == from_xml
    assert "Subtree 'go_second' (tree 'GoTo')" in from_xml
    assert "in  value <- patrol/leg2/go_second.report" in from_xml
