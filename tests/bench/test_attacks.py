"""The hostile-input probe in its quick form, in-process (a few seconds, loopback only)."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks import Check, probe

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def checks() -> dict[str, Check]:
    result = asyncio.run(asyncio.wait_for(probe(quick=True), timeout=30))
    return {c.name: c for c in result}


@pytest.mark.parametrize(
    "name",
    [
        "fake_states",
        "junk",
        "oversized",
        "hello_flood",
        "mission",
    ],
)
def test_attack_changes_nothing(checks: dict[str, Check], name: str) -> None:
    check = checks[name]
    assert check.passed, json.dumps(check.figures)


@pytest.fixture(scope="module")
def member_checks() -> dict[str, Check]:
    from btcap.bench.attacks_member import probe_members

    result = asyncio.run(asyncio.wait_for(probe_members(quick=True), timeout=60))
    return {name: Check(name, passed, figures) for name, passed, figures in result}


@pytest.mark.parametrize("name", ["award", "lease", "heartbeat_churn", "sybil"])
def test_member_attack_is_bounded(member_checks: dict[str, Check], name: str) -> None:
    check = member_checks[name]
    assert check.passed, json.dumps(check.figures)
