"""Start-up stays cheap: ``import btcap`` and every ``btcap ... --help`` load none of the
heavy optional modules (scipy, numpy, aiohttp, matplotlib, pyzmq, the monitor, the actor
runtime); each is imported by the code that uses it, when it runs.

Checked in a fresh interpreter, by what ends up in ``sys.modules`` (never by a clock).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

#: Nothing here may be imported just to import btcap or to print help.
HEAVY = (
    "scipy",
    "numpy",
    "aiohttp",
    "matplotlib",
    "zmq",
    "structlog",
    "rich",
    "btcap.actors",
    "btcap.transports",
    "btcap.team",
    "btcap.monitor.monitor",
    "btcap.monitor.server",
    "btcap.monitor.plot",
)


def _loaded(code: str) -> list[str]:
    """The modules a fresh interpreter holds after running ``code``."""
    script = textwrap.dedent(code) + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0, done.stderr
    modules: list[str] = json.loads(done.stdout.splitlines()[-1])
    return modules


def _heavy(modules: list[str]) -> list[str]:
    return [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]


def test_import_btcap_loads_nothing_heavy() -> None:
    modules = _loaded("import btcap")
    assert _heavy(modules) == []
    assert "btcap.monitor" not in modules
    assert [m for m in modules if m.startswith("btcap.")] == ["btcap._lazy"]


def test_using_a_name_of_btcap_imports_only_what_it_needs() -> None:
    """A behavior tree needs the runtime, not the monitor, the allocation planners or
    the simulation."""
    modules = _loaded("import btcap\nbtcap.Sequence\nbtcap.Agent")
    assert "btcap.actors" in modules  # the check can see an import
    assert not [m for m in modules if m.split(".")[0] in ("scipy", "numpy", "aiohttp")]
    assert not [m for m in modules if m.startswith(("btcap.monitor", "btcap.sim"))]


def test_every_help_loads_nothing_heavy() -> None:
    """``btcap --help`` and the help of every command and subcommand, in one process."""
    modules = _loaded(
        """
        import argparse, contextlib, io
        from btcap.cli import build_parser, main

        def helps(parser, prefix):
            yield [*prefix, "--help"]
            for action in parser._actions:
                if isinstance(action, argparse._SubParsersAction):
                    for name, sub in action.choices.items():
                        yield from helps(sub, [*prefix, name])

        argvs = list(helps(build_parser(), []))
        assert len(argvs) > 10, argvs
        for argv in argvs:
            with contextlib.redirect_stdout(io.StringIO()) as out:
                assert main(argv) == 0, argv
            assert "usage: btcap" in out.getvalue(), argv
        """
    )
    assert "btcap.sim.cli" in modules  # the plugin commands were loaded
    assert _heavy(modules) == []


@pytest.mark.parametrize("argv", [["--help"], ["--version"]])
def test_the_console_script_prints_help_and_version(argv: list[str]) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "btcap", *argv],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert done.stdout.startswith(("usage: btcap", "btcap "))
