"""A library stays silent: btcap logs through ``logging`` and the application decides."""

from __future__ import annotations

import ast
import asyncio
import logging
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import anyio
import pytest
import structlog

from btcap.actors import Actor, ActorSystem, Address, Message, configure_logging, handler

ROOT = Path(__file__).resolve().parents[2]


class Boom(Message):
    pass


class Fragile(Actor):
    @handler
    def on_boom(self, msg: Boom) -> None:
        raise RuntimeError("handler broke")


async def _agent_like_run() -> None:
    """What an embedding program does: warnings, errors and info events all happen."""
    async with ActorSystem("robot") as system:
        fragile = system.spawn(Fragile(), "fragile")
        fragile.tell(Boom())  # actor.handler_failed, at error level
        system.tell(Address("robot", "nobody"), Boom())  # actors.dead_letter, at info
        system._count_drop("mailbox_full", fragile.address, Boom())  # a warning
        await asyncio.sleep(0)


@pytest.fixture
def plain_logs() -> None:
    """Overrides the package's capture: these tests look at real output."""


@pytest.fixture
def unconfigured() -> Iterator[None]:
    """structlog and the root logger as a program that configured nothing has them."""
    saved = structlog.get_config()
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    structlog.reset_defaults()
    try:
        yield
    finally:
        structlog.configure(**saved)
        if not saved["processors"]:
            structlog.reset_defaults()
        root.handlers[:] = handlers
        root.setLevel(level)


@pytest.mark.usefixtures("unconfigured")
async def test_an_embedded_runtime_prints_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    with anyio.fail_after(2):
        await _agent_like_run()
    assert capsys.readouterr() == ("", "")


def test_a_program_that_configures_nothing_sees_nothing() -> None:
    """No pytest handlers here: Python's last-resort handler would print warnings."""
    code = (
        "import asyncio, logging, structlog\n"
        "from tests.actors.test_logging import _agent_like_run\n"
        "asyncio.run(_agent_like_run())\n"
        "assert not structlog.is_configured()\n"
        "assert logging.getLogger().handlers == []\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")


@pytest.mark.usefixtures("unconfigured")
async def test_standard_logging_turns_the_events_on(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="btcap")
    with anyio.fail_after(2):
        await _agent_like_run()
    records = [(r.name, r.levelname, r.getMessage().split()[0]) for r in caplog.records]
    assert ("btcap.actors.cell", "ERROR", "actor.handler_failed") in records
    assert ("btcap.actors.system", "INFO", "actors.dead_letter") in records
    assert ("btcap.actors.system", "WARNING", "actors.dropped") in records
    dead = next(r for r in caplog.records if r.getMessage().startswith("actors.dead_letter"))
    assert "to=robot/nobody" in dead.getMessage()
    failed = next(r for r in caplog.records if r.levelname == "ERROR")
    assert failed.exc_info is not None
    assert "handler broke" in str(failed.exc_info[1])


@pytest.mark.usefixtures("unconfigured")
async def test_a_level_the_logger_drops_is_never_formatted(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.ERROR, logger="btcap")
    with anyio.fail_after(2):
        await _agent_like_run()
    assert [r.levelname for r in caplog.records if r.name.startswith("btcap")] == ["ERROR"]


@pytest.mark.usefixtures("unconfigured")
async def test_configure_logging_renders_events_on_stderr(
    capsys: pytest.CaptureFixture[str],
) -> None:
    configure_logging("info")
    with anyio.fail_after(2):
        await _agent_like_run()
    out, err = capsys.readouterr()
    assert out == ""
    for event in ("actor.handler_failed", "actors.dead_letter", "actors.dropped"):
        assert event in err
    assert "handler broke" in err  # the traceback is rendered


@pytest.mark.usefixtures("unconfigured")
async def test_configure_logging_json_and_level(capsys: pytest.CaptureFixture[str]) -> None:
    configure_logging("warning")
    configure_logging("warning", json=True)  # a second call replaces the first handler
    with anyio.fail_after(2):
        await _agent_like_run()
    lines = capsys.readouterr().err.splitlines()
    events = [line for line in lines if line.startswith("{")]
    assert len(events) == len(lines) == 2, lines
    assert '"event": "actor.handler_failed"' in events[0]
    assert '"logger": "btcap.actors.cell"' in events[0]
    assert '"event": "actors.dropped"' in events[1]


def test_configure_logging_rejects_unknown_levels() -> None:
    with pytest.raises(ValueError, match="log level 'loud'"):
        configure_logging("loud")


def test_importing_btcap_configures_no_logging() -> None:
    code = (
        "import logging, structlog, btcap, btcap.actors, btcap.transports\n"
        "assert not structlog.is_configured()\n"
        "assert logging.getLogger().handlers == []\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_every_btcap_logger_goes_through_logging() -> None:
    """``structlog.get_logger`` would print to stdout in a program that configured nothing."""
    from btcap_sources import modules  # here: a subprocess imports this file from the root

    bad = []
    paths = list(modules().values())
    assert any(p.parts[-2] == "sim" for p in paths)
    for path in sorted(paths):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (
                isinstance(node, ast.Attribute)
                and node.attr == "get_logger"
                and isinstance(node.value, ast.Name)
                and node.value.id == "structlog"
            ):
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not bad, "use btcap.transports.log.get_logger: " + ", ".join(bad)


@pytest.mark.usefixtures("unconfigured")
def test_a_redirected_log_has_no_colour_codes(capsys: pytest.CaptureFixture[str]) -> None:
    configure_logging("info")
    logging.getLogger("btcap.test").warning("plain.event")
    err = capsys.readouterr().err
    assert "plain.event" in err
    assert "\x1b[" not in err


@pytest.mark.usefixtures("unconfigured")
@pytest.mark.parametrize(("no_color", "coloured"), [("", True), ("1", False)])
def test_a_terminal_gets_colours_unless_no_color(
    monkeypatch: pytest.MonkeyPatch, no_color: str, coloured: bool
) -> None:
    monkeypatch.setenv("NO_COLOR", no_color)
    monkeypatch.delenv("FORCE_COLOR", raising=False)
    main_fd, tty_fd = os.openpty()
    with os.fdopen(tty_fd, "w") as tty, os.fdopen(main_fd, "rb", buffering=0) as reader:
        monkeypatch.setattr(sys, "stderr", tty)
        configure_logging("info")
        logging.getLogger("btcap.test").warning("tty.event")
        tty.flush()
        seen = reader.read(4096)
    assert b"tty.event" in seen
    assert (b"\x1b[" in seen) is coloured


@pytest.mark.usefixtures("unconfigured")
def test_wanted_says_whether_an_event_would_go_anywhere() -> None:
    """A hot path may skip an event nobody keeps: not taken by ``logging`` and structlog
    unconfigured (or configured to filter by level) means dropped; a ``logging`` level
    that takes it, or structlog capturing without a level filter, means kept."""
    from btcap.transports.log import wanted

    name = "btcap.test_wanted"
    logging.getLogger(name).setLevel(logging.WARNING)
    try:
        assert not wanted(name, logging.INFO)
        assert wanted(name, logging.WARNING)
        configure_logging("warning")
        assert not wanted(name, logging.INFO)  # configured, filtered by level
        with structlog.testing.capture_logs():
            assert wanted(name, logging.INFO)
        logging.getLogger(name).setLevel(logging.INFO)
        assert wanted(name, logging.INFO)
    finally:
        logging.getLogger(name).setLevel(logging.NOTSET)


def test_every_logger_is_named_after_its_module() -> None:
    """Logger names follow the packages (``btcap.team.runtime.mission``...), so one
    ``logging.getLogger("btcap.team").setLevel(...)`` reaches a whole subpackage; the only
    other name is the BT ``Log`` leaf's, which a tree's author switches on by name."""
    from btcap_sources import modules

    named = []
    for mod, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id == "get_logger"
                and node.args
            ):
                arg = node.args[0]
                if not (isinstance(arg, ast.Name) and arg.id in ("__name__", "LOG_LOGGER")):
                    named.append(f"{mod}: get_logger({ast.unparse(arg)})")
    assert not named, named
