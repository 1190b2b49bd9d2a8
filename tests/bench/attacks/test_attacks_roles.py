"""The roles and names probe (bench/attacks/roles.py): every attack refused, the mission
untouched (a few seconds, loopback only)."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks.probe import MORE_PROBES
from btcap.bench.attacks.roles import probe_roles

pytestmark = pytest.mark.slow

NAMES = [
    "observer_key_drives",
    "observer_id_drives",
    "operator_executes",
    "second_live_r1",
    "roles_mission",
]


@pytest.fixture(scope="module")
def results() -> dict[str, tuple[bool, dict[str, object]]]:
    found = asyncio.run(asyncio.wait_for(probe_roles(quick=True), timeout=30))
    return {name: (passed, figures) for name, passed, figures in found}


@pytest.mark.parametrize("name", NAMES)
def test_refused_by_role_or_name(
    results: dict[str, tuple[bool, dict[str, object]]], name: str
) -> None:
    passed, figures = results[name]
    assert passed, json.dumps(figures, default=str)


def test_the_probe_runs_with_the_others() -> None:
    assert probe_roles in MORE_PROBES
