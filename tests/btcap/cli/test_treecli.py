"""``btcap tree``: your own node types and interfaces, ``run``, and pictures via Graphviz."""

from __future__ import annotations

import logging
import re
import shutil
import sys
import textwrap
import uuid
import warnings
from collections.abc import Iterator
from pathlib import Path

import pytest

import btcap.cli
from btcap import RestartLoopWarning
from btcap.actors import configure_logging
from btcap.bt.files import dumps_tree, load_tree
from btcap.bt.leaves import LOG_LOGGER
from btcap.cli import main

ROOT = Path(__file__).resolve().parents[3]
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
      <btcap.Log message="docking" value="{s}"/>
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
    assert "in  value <- {s} (wire from Sequence/DockInputs.station)" in out


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
    capsys.readouterr()
    # A class named like a btcap built-in is the user's Log in XML, user.Log in YAML.
    assert main(["tree", "nodes", "--load", f"{mod}:clash", "Log", "user.Log"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Log: Logs ``message``")
    assert "\nuser.Log: \n" in out
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
        (
            '<Sleep msec="60000"/>',
            ["--fast", "--max-ticks", "3"],
            3,
            "halted after 3 ticks at --max-ticks 3; still running: Sleep",
        ),
        (
            '<Sleep msec="600000"/>',
            ["--fast"],
            3,
            "halted after 600 ticks at --timeout 60 s (virtual time); still running: Sleep",
        ),
        (
            '<Sleep msec="600000"/>',
            ["--fast", "--timeout", "none"],
            0,
            "succeeded after 6001 ticks",
        ),
        ('<Sleep msec="600000"/>', ["--fast", "--timeout", "0"], 0, "succeeded after 6001 ticks"),
        (
            '<Sleep msec="2000"/>',
            ["--fast", "--timeout", "1.5"],
            3,
            "halted after 15 ticks at --timeout 1.5 s (virtual time); still running: Sleep",
        ),
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


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rate", "0"], "--rate 0.0: expected a finite number of ticks per second > 0"),
        (["--rate", "inf"], "--rate inf: expected a finite number of ticks per second > 0"),
        (["--max-ticks", "0"], "--max-ticks 0: expected at least 1"),
        (["--timeout", "-1"], "--timeout -1: expected seconds > 0, or 0 or none for no limit"),
        (["--timeout", "soon"], "--timeout soon: expected seconds > 0, or 0 or none for no limit"),
        (["--timeout", "inf"], "--timeout inf: expected seconds > 0, or 0 or none for no limit"),
        (["--timeout", "nan"], "--timeout nan: expected seconds > 0, or 0 or none for no limit"),
    ],
)
def test_run_refuses_bad_limits(
    capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["tree", "run", *args, str(PATROL_XML)]) == 2
    assert capsys.readouterr().err.strip() == f"btcap: error: {message}"


RESTART_LOOP = """\
btcap: 1
root:
  type: ReactiveSequence
  name: s
  children:
    - {type: AlwaysSuccess, name: check}
    - type: Repeat
      name: rep
      children: [{type: Wait, name: w, options: {seconds: 0.2}}]
    - {type: AlwaysRunning, name: work}
"""


@pytest.mark.parametrize("how", ["flag", "environment"])
def test_run_of_a_tree_in_a_restart_loop_warns_and_stops_at_the_limit(
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    how: str,
) -> None:
    path = tmp_path / "hang.yaml"
    path.write_text(RESTART_LOOP)
    monkeypatch.setenv("BTCAP_DEBUG", "1" if how == "environment" else "0")
    flags = ["--debug"] if how == "flag" else []
    with pytest.warns(RestartLoopWarning, match="node 's/work' \\(AlwaysRunning\\) was halted"):
        code = main(["tree", "run", "--fast", "--timeout", "30", *flags, str(path)])
    assert code == 3
    last = capsys.readouterr().out.splitlines()[-1]
    assert last == "halted after 300 ticks at --timeout 30 s (virtual time); still running: s/rep/w"


def test_run_shows_log_nodes_on_stderr_whatever_the_log_level(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    # The CLI's own logging set-up, as a user gets it (conftest puts logging back after).
    monkeypatch.setattr(btcap.cli, "configure_logging", configure_logging)
    logger = logging.getLogger(LOG_LOGGER)
    before = logger.level
    path = tmp_path / "say.yaml"
    path.write_text(
        "btcap: 1\n"
        "root:\n"
        "  type: Sequence\n"
        "  name: root\n"
        "  children:\n"
        "    - {type: Wait, name: w, options: {seconds: 30}}\n"
        "    - {type: Log, name: say, options: {message: hello from the tree}}\n"
        "    - {type: Log, name: quiet, options: {message: only when debugging, level: debug}}\n"
    )
    assert main(["tree", "run", "--fast", str(path)]) == 0
    out = capsys.readouterr()
    assert out.out.splitlines()[-1] == "succeeded after 301 ticks"
    lines = [line for line in out.err.splitlines() if "hello from the tree" in line]
    assert len(lines) == 1
    assert "node=root/say" in lines[0]
    assert "only when debugging" not in out.err
    assert logger.level == before  # put back: the library configures no logging
    assert main(["--log-level", "debug", "tree", "run", "--fast", str(path)]) == 0
    assert "only when debugging" in capsys.readouterr().err


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
    assert capsys.readouterr().out == _without_entries(from_xml)
    assert "Subtree 'go_second' (tree 'GoTo')" in from_xml
    assert "in  value <- {report} (wire from patrol/leg2/go_second.report)" in from_xml


def _without_entries(text: str) -> str:
    """What the YAML dump shows of an XML outline: it names no blackboard entries."""
    out = []
    for line in text.splitlines(keepends=True):
        m = re.search(r"(· in  \S+ <- )\{[^}]*\} \(wire from (.*)\)$", line.rstrip("\n"))
        if m:
            out.append(line[: m.start()] + m.group(1) + m.group(2) + "\n")
        elif "{" not in line:
            out.append(line)
    return "".join(out)


# -- blackboard entries ---------------------------------------------------------------
NEED = '''\
from btcap import Leaf, State


class Need(Leaf):
    """Succeeds when its goal is to the east."""

    INPUTS = {"goal": tuple[float, float]}

    def on_tick(self) -> State:
        return State.SUCCEEDED if self.inputs["goal"][0] > 0 else State.FAILED
'''


def _need(tmp_path: Path) -> tuple[Path, Path]:
    """A module with the Need node (named afresh: a module loads once) and a tree using it."""
    need = tmp_path / f"need_{uuid.uuid4().hex[:8]}.py"
    need.write_text(NEED)
    xml = '<root BTCPP_format="4"><BehaviorTree ID="M"><Need goal="{goal}"/></BehaviorTree></root>'
    return need, _tree(tmp_path, xml)


@pytest.mark.parametrize(
    ("args", "file", "code", "out"),
    [
        (["--set", "goal=1;2"], None, 0, "goal = (1.0, 2.0)"),
        ([], "goal: [-1, 2]\n", 1, "goal = (-1.0, 2.0)"),
        (["--set", "goal=3;4"], "goal: [-1, 2]\n", 0, "goal = (3.0, 4.0)"),
    ],
)
def test_run_sets_blackboard_entries_the_tree_reads(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    args: list[str],
    file: str | None,
    code: int,
    out: str,
) -> None:
    need, tree = _need(tmp_path)
    if file is not None:
        (tmp_path / "entries.yaml").write_text(file)
        args = ["--set-file", str(tmp_path / "entries.yaml"), *args]
    assert main(["tree", "run", "--load", str(need), *args, str(tree)]) == code
    assert out in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "blackboard entries read but never written nor set: {goal} (tuple[float, float]"),
        (["--set", "gaol=1;2"], "no entry 'gaol' that the application can set (entries: goal)"),
        (["--set", "goal=east"], "blackboard entry 'goal' of tree 'M': expected tuple"),
        (["--set", "goal"], "--set 'goal': expected KEY=VALUE"),
    ],
)
def test_run_refuses_missing_unknown_and_mistyped_entries(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, args: list[str], message: str
) -> None:
    need, tree = _need(tmp_path)
    assert main(["tree", "run", "--load", str(need), *args, str(tree)]) != 0
    assert message in capsys.readouterr().err


def test_run_tells_a_node_error_once_in_its_log_not_again_as_a_warning(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The command's log line says it; the NodeErrorWarning a library user gets by
    default would say it twice."""
    monkeypatch.setattr(btcap.cli, "configure_logging", configure_logging)
    module = tmp_path / f"broken_{uuid.uuid4().hex[:8]}.py"
    module.write_text(
        "from btcap import Leaf, State\n\n\n"
        "class Grip(Leaf):\n"
        "    def on_tick(self) -> State:\n"
        '        raise ValueError("gripper offline")\n'
    )
    path = tmp_path / "grip.yaml"
    path.write_text(
        "btcap: 1\nroot:\n  type: Fallback\n  name: try\n  children:\n"
        "    - {type: Grip, name: grip}\n    - {type: AlwaysSuccess, name: skip}\n"
    )
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        assert main(["tree", "run", "--fast", "--load", str(module), str(path)]) == 0
    sys.modules.pop(module.stem, None)
    assert [w.category for w in said] == []
    err = capsys.readouterr().err
    assert err.count("btcap.node_error") == 1
    assert "NodeErrorWarning" not in err
