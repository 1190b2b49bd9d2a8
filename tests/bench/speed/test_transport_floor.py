"""The ask benchmark's floors: hand-written event-loop echoes and blocking pyzmq, each in
a peer process, answer every ask with what was sent (so the figures measure round trips)."""

from __future__ import annotations

import tempfile

import anyio
import pytest

from btcap.bench.speed.transport import _make_keys
from btcap.bench.speed.transport_floor import PAYLOAD, floor_tcp, raw_zmq_tcp_blocking


@pytest.mark.parametrize("pair", [False, True], ids=["one_connection", "btcaps_shape"])
@pytest.mark.parametrize("curve", [False, True], ids=["plain", "curve"])
async def test_the_hand_written_floor_echoes_every_ask(pair: bool, curve: bool) -> None:
    with tempfile.TemporaryDirectory() as tmp, anyio.fail_after(20):
        keys = None
        if curve:
            _make_keys(tmp)
            keys = tmp
        async with floor_tcp("asyncio", keys, pair=pair) as (ask, pids):
            assert len(pids) == 1
            for i in range(50):
                assert await ask(i) == PAYLOAD


@pytest.mark.parametrize("curve", [False, True], ids=["plain", "curve"])
async def test_blocking_pyzmq_echoes_every_ask(curve: bool) -> None:
    with tempfile.TemporaryDirectory() as tmp, anyio.fail_after(20):
        keys = None
        if curve:
            _make_keys(tmp)
            keys = tmp
        async with raw_zmq_tcp_blocking(keys) as (ask, _pids):
            for i in range(50):
                assert await ask(i) == PAYLOAD
