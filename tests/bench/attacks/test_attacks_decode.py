"""The decoding-cost probe (bench/attacks/decode.py): every nested frame refused before
it is decoded, counted, nothing taken, no teammate failed, every ask answered (quick
mode: 0.9 MB frames; loopback only). Judged by counts: the CPU and latency figures are
the bench's to print."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks.decode import probe_decode
from btcap.bench.attacks.probe import MORE_PROBES

pytestmark = pytest.mark.slow

NAMES = [
    "observer_nested_calls",
    "stranger_nested_calls",
    "stranger_nested_small",
    "member_nested_calls",
    "member_nested_tasks",
]


@pytest.fixture(scope="module")
def results() -> dict[str, tuple[bool, dict[str, object]]]:
    found = asyncio.run(asyncio.wait_for(probe_decode(quick=True), timeout=240))
    return {name: (passed, figures) for name, passed, figures in found}


@pytest.mark.parametrize("name", NAMES)
def test_refused_before_decoding(
    results: dict[str, tuple[bool, dict[str, object]]], name: str
) -> None:
    passed, figures = results[name]
    assert passed, json.dumps(figures, default=str)
    assert figures["taken"] == 0
    assert figures["refused"] == figures["frames"]


def test_the_probe_runs_with_the_others() -> None:
    assert probe_decode in MORE_PROBES
