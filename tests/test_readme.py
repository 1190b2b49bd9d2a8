"""Every code block of the README and the guide (docs/) works as written.

The convention (also stated at the top of README.md): ```python blocks run, each as a
whole program in its own interpreter; ```yaml blocks load as tree files, agent files,
scenarios or team files; ```sh lines are commands btcap's parser accepts (cheap ones
run), make targets or scripts of this repository; ```text and ```console blocks are
output, shown and not run. A block without a tag is an error, so nobody's example
silently escapes the test. A block right after ``<!-- copy: PATH -->`` is a copy of that
file (tests/test_docs.py keeps it equal), which is tested on its own.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

import btcap.cli
from btcap.bt.files import dump_tree, loads_tree
from btcap.sim.mission.scenario import load_scenario
from btcap.sim.world.model import load_team
from btcap.team.deployment.agentconfig import load_agent_file

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_FENCE = re.compile(r"^```([\w-]*)[^\n]*\n(.*?)^```[ \t]*$", re.M | re.S)
_SHOWN = {"text", "console"}
_CHECKED = {"python", "yaml", "sh"}
#: ``btcap`` subcommands cheap enough to run for real (the rest are parsed only).
_RUN = {("tree", "validate"), ("tree", "show"), ("tree", "nodes"), ("tree", "run")}


@dataclass(frozen=True)
class Block:
    page: Path
    line: int
    lang: str
    code: str
    copied: bool  # a copy of a file of the repository, tested on its own

    def __str__(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line} ({self.lang or 'no tag'})"


def _blocks() -> list[Block]:
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for m in _FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            copied = text[: m.start()].endswith("-->\n") and text[: m.start()].rsplit("\n", 2)[
                -2
            ].startswith("<!-- copy: ")
            found.append(Block(page, line, m[1], m[2], copied))
    return found


BLOCKS = _blocks()


def _of(lang: str) -> list[Block]:
    return [b for b in BLOCKS if b.lang == lang and not b.copied]


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() would configure logging onto this test's captured stderr (see test_cli_run)."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def test_every_block_says_what_it_is() -> None:
    untagged = [str(b) for b in BLOCKS if b.lang not in _SHOWN | _CHECKED]
    assert not untagged, f"tag these blocks python, yaml, sh, text or console: {untagged}"
    assert len(_of("python")) >= 3


def run_block(block: Block, folder: Path) -> subprocess.CompletedProcess[str]:
    """In its own interpreter, from the repository's root, as a reader would paste it."""
    script = folder / "block.py"
    script.write_text(block.code, encoding="utf-8")
    return subprocess.run(
        [sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=60
    )


def _run_in_a_folder_of_its_own(block: Block) -> subprocess.CompletedProcess[str]:
    with tempfile.TemporaryDirectory(prefix="btcap-block-") as folder:
        return run_block(block, Path(folder))


#: The selected python blocks' runs, started once the suite is collected (tests/conftest.py
#: calls :func:`start_ahead`): one at a time on a thread, each exactly as the test would run
#: it (its own interpreter waits on nothing of this one), so they run beside the tests
#: collected before this module rather than after them. Not under pytest-xdist, whose
#: workers have the cores; a block not started here is run by its test.
_ahead: dict[str, Future[subprocess.CompletedProcess[str]]] = {}
_pool: ThreadPoolExecutor | None = None


def start_ahead(items: Sequence[pytest.Item]) -> None:
    global _pool
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    for item in items:
        block = getattr(item, "callspec", None) and item.callspec.params.get("block")
        if getattr(item, "originalname", "") == "test_python_block_runs_as_written" and block:
            if _pool is None:
                _pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="readme-blocks")
            _ahead[str(block)] = _pool.submit(_run_in_a_folder_of_its_own, block)


def stop_ahead() -> None:
    """Drop the runs not started; wait for the one running (each is bounded: 60 s)."""
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None
    _ahead.clear()


@pytest.mark.parametrize("block", _of("python"), ids=str)
def test_python_block_runs_as_written(block: Block, tmp_path: Path) -> None:
    """In its own interpreter, from the repository's root, as a reader would paste it."""
    ahead = _ahead.pop(str(block), None)
    done = run_block(block, tmp_path) if ahead is None else ahead.result()
    assert done.returncode == 0, f"{block}:\n{block.code}\n{done.stderr}"


@pytest.mark.parametrize("block", _of("yaml"), ids=str)
def test_yaml_block_loads(block: Block, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    data = yaml.safe_load(block.code)
    if "root" in data:  # a tree file: the README's is the quickstart tree of examples/
        tree = dump_tree(loads_tree(block.code))
        assert tree.root.name, str(block)
        return
    if "robots" in data:  # a scenario
        path = tmp_path / "scenario.yaml"
        path.write_text(block.code, encoding="utf-8")
        assert load_scenario(path).name == data["name"]
        return
    if "models" in data:  # a team file
        path = tmp_path / "team.yaml"
        path.write_text(block.code, encoding="utf-8")
        assert set(load_team(path)) == set(data["models"])
        return
    assert "robot" in data, f"{block}: neither a tree, agent, scenario nor team file"
    # An agent file as it would sit in examples/team/, with its teammates' keys made.
    shutil.copytree(ROOT / "examples" / "capabilities", tmp_path / "capabilities")
    keys = tmp_path / "keys"
    keys.mkdir()
    monkeypatch.setenv("BTCAP_KEYS", str(keys))
    argv = ["keys", "new", data["robot"], "--role", "robot", "--dir", str(keys)]
    assert btcap.cli.main(argv) == 0
    path = tmp_path / "team" / "robot.yaml"
    path.parent.mkdir()
    path.write_text(block.code, encoding="utf-8")
    assert load_agent_file(path).robot == data["robot"]


def _commands(block: Block) -> list[list[str]]:
    lines = [line.split(" #", 1)[0].strip() for line in block.code.splitlines()]
    return [shlex.split(line) for line in lines if line and not line.startswith("#")]


def _from_root(arg: str) -> str:
    """A relative path the docs give from the repository's top, made absolute."""
    return str(ROOT / arg) if not arg.startswith("-") and (ROOT / arg).exists() else arg


def _make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return set(re.findall(r"^([\w-]+):", text, re.M))


@pytest.mark.parametrize("block", _of("sh"), ids=str)
def test_shell_block_commands_exist(
    block: Block,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
) -> None:
    monkeypatch.chdir(ROOT)
    for argv in _commands(block):
        head, args = argv[0], argv[1:]
        if head == "make":
            assert set(args) <= _make_targets(), f"{block}: {argv}: no such make target"
        elif head in ("pip", "python", "python3") or head.endswith("/python"):
            continue  # the installer's business
        elif Path(head).name == "btcap":
            words = tuple(a for a in args if not a.startswith("-"))[:2]
            if "--help" in args or "--version" in args or words in _RUN:
                # cheap: run it for real, in a folder of its own (a file it writes, such as
                # --btlog patrol.btlog, must not land in the repository)
                monkeypatch.chdir(tmp_path)
                code = btcap.cli.main([_from_root(a) for a in args])
                monkeypatch.chdir(ROOT)
            else:
                parser = btcap.cli.build_parser()
                try:
                    parser.parse_args(args)
                    code = 0
                except SystemExit as exc:
                    code = exc.code if isinstance(exc.code, int) else 2
            out, err = capsys.readouterr()
            assert code == 0, f"{block}: {shlex.join(argv)}: exit {code}\n{out}{err}"
        else:
            script = ROOT / head
            assert script.is_file(), f"{block}: {head}: not a command this test knows"
            assert script.stat().st_mode & 0o111, f"{block}: {head} is not executable"
