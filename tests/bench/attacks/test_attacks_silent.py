"""The silent-connections probe (bench/attacks/silent.py): connections that complete the
handshake and say nothing are held at most up to the cap and closed after the deadline,
while an unlimited target holds every one (a few seconds, loopback only)."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks.probe import MORE_PROBES
from btcap.bench.attacks.silent import probe_silent

pytestmark = pytest.mark.slow


def test_silent_connections_are_bounded() -> None:
    [(name, passed, figures)] = asyncio.run(asyncio.wait_for(probe_silent(quick=True), 60))
    assert name == "silent_connections"
    assert passed, json.dumps(figures)
    assert figures["held_without_limits"] >= 0.9 * figures["connections"]  # the peer figure


def test_the_probe_runs_with_the_others() -> None:
    assert probe_silent in MORE_PROBES
