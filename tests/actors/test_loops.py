"""Which event loop btcap processes run on: uvloop when installed, unless told otherwise."""

from __future__ import annotations

import asyncio

import pytest

from btcap.actors.loops import LOOP_ENV, loop_name, run

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
