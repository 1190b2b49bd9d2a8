"""The examples the README shows work, and the Python and YAML quickstart trees agree."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import anyio
import msgspec

from btcap import State
from btcap.actors import Clock
from btcap.bt.files import dump_tree, load_tree

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _module(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_python_and_yaml_quickstart_trees_are_the_same() -> None:
    from_python = dump_tree(_module("quickstart").build())
    from_yaml = dump_tree(load_tree(EXAMPLES / "trees" / "quickstart.yaml"))
    assert msgspec.to_builtins(from_python.root) == msgspec.to_builtins(from_yaml.root)
    assert msgspec.to_builtins(from_python.wires) == msgspec.to_builtins(from_yaml.wires)


async def test_quickstart_tree_runs_to_success() -> None:
    tree = _module("quickstart").build()
    tree.clock = Clock(speedup=50)
    with anyio.fail_after(5):
        assert await tree.run(rate_hz=50) is State.SUCCEEDED
    await tree.shutdown()


async def test_two_robot_example_runs() -> None:
    with anyio.fail_after(20):
        await _module("two_robots").main()


README = EXAMPLES.parent / "README.md"


def _python_blocks() -> list[str]:
    text = README.read_text()
    return [part.split("```", 1)[0] for part in text.split("```python\n")[1:]]


def test_every_python_block_of_the_readme_runs_as_written(tmp_path: Path) -> None:
    """Each block in its own interpreter, as a reader would paste it."""
    blocks = _python_blocks()
    assert len(blocks) >= 2
    for i, block in enumerate(blocks):
        script = tmp_path / f"block{i}.py"
        script.write_text(block)
        done = subprocess.run(
            [sys.executable, str(script)], capture_output=True, text=True, timeout=60
        )
        assert done.returncode == 0, f"README python block {i}:\n{block}\n{done.stderr}"
