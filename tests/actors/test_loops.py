"""Which event loop btcap processes run on: uvloop when installed, unless told otherwise."""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Iterator
from typing import Any

import pytest
from structlog.testing import capture_logs

from btcap.actors.loops import LOOP_ENV, STALL_S, loop_name, report_stalls, run

uvloop = pytest.importorskip("uvloop")  # the optional 'fast' extra (in dev)


async def _loop_type() -> str:
    return type(asyncio.get_running_loop()).__module__.split(".")[0]


def test_uvloop_is_the_default_when_installed() -> None:
    assert loop_name({}) == "uvloop"
    assert loop_name({LOOP_ENV: "auto"}) == "uvloop"
    assert run(_loop_type(), {}) == "uvloop"


def test_btcap_loop_asyncio_keeps_the_stock_loop() -> None:
    assert loop_name({LOOP_ENV: "asyncio"}) == "asyncio"
    assert run(_loop_type(), {LOOP_ENV: " AsyncIO "}) == "asyncio"


def test_an_unknown_loop_is_refused_naming_the_variable() -> None:
    coro = _loop_type()
    with pytest.raises(ValueError, match=r"BTCAP_LOOP='tokio': expected one of auto, asyncio"):
        run(coro, {LOOP_ENV: "tokio"})
    assert coro.cr_frame is None  # closed, not left to warn "never awaited"


def test_uvloop_asked_for_but_missing_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    import btcap.actors.loops as loops

    monkeypatch.setattr(loops, "_uvloop_installed", lambda: False)
    assert loop_name({}) == "asyncio"
    with pytest.raises(ValueError, match="uvloop is not installed"):
        loop_name({LOOP_ENV: "uvloop"})


def _burn(seconds: float) -> None:
    """Hold the loop for ``seconds`` of this thread's CPU time (wall time is longer still,
    however loaded the machine: so the loop's own timing always sees a stall)."""
    start = time.thread_time()
    while time.thread_time() - start < seconds:
        pass


def hog_callback() -> None:
    _burn(2 * STALL_S)


async def hog_task() -> None:
    _burn(2 * STALL_S)


async def _stalls(debug: bool) -> tuple[bool, float]:
    loop = asyncio.get_running_loop()
    loop.set_debug(debug)
    armed = report_stalls(loop)
    for _ in range(2):  # the same sites twice: reported once each
        loop.call_soon(hog_callback)
        await asyncio.sleep(0)
        await loop.create_task(hog_task())
    return armed, loop.slow_callback_duration


@pytest.fixture
def no_stall_filter() -> Iterator[None]:
    yield
    asyncio_log = logging.getLogger("asyncio")
    for f in list(asyncio_log.filters):
        asyncio_log.removeFilter(f)


def _reported(logs: list[dict[str, Any]]) -> list[str]:
    return [e["callback"] for e in logs if e["event"] == "loop.stalled" and "hog" in e["callback"]]


@pytest.mark.usefixtures("no_stall_filter")
@pytest.mark.parametrize("loop", ["asyncio", "uvloop"])
def test_in_debug_mode_a_stall_is_reported_once_per_callback_with_its_name(loop: str) -> None:
    with capture_logs() as logs:
        armed, threshold = run(_stalls(debug=True), {LOOP_ENV: loop})
    assert armed
    assert threshold == STALL_S
    assert sorted(_reported(logs)) == ["hog_callback", "hog_task"]
    stalled = next(e for e in logs if e.get("callback") == "hog_task")
    assert stalled["log_level"] == "warning"
    assert stalled["seconds"] >= 2 * STALL_S


@pytest.mark.usefixtures("no_stall_filter")
def test_out_of_debug_mode_nothing_is_timed() -> None:
    with capture_logs() as logs:
        armed, _ = run(_stalls(debug=False), {LOOP_ENV: "asyncio"})
    assert not armed
    assert _reported(logs) == []
