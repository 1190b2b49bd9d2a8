"""The examples the README shows work, and the Python and YAML quickstart trees agree
(the README's own code blocks: tests/test_readme.py)."""

from __future__ import annotations

import importlib.util
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
