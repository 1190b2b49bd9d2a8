"""The hostile-input probe in its quick form, in-process (a few seconds, loopback only)."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks import Check, probe

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def checks() -> dict[str, Check]:
    result = asyncio.run(asyncio.wait_for(probe(quick=True), timeout=120))
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


def test_no_node_action_attack_succeeds(checks: dict[str, Check]) -> None:
    """The node-action probe (bench/attacks_nodes.py) runs in the same probe: five
    attacks, keyless and with a member's CURVE key, each refused and counted."""
    nodes = {name: c for name, c in checks.items() if name.startswith("node_")}
    assert len(nodes) == 10
    failed = {name: c.figures for name, c in nodes.items() if not c.passed}
    assert not failed, json.dumps(failed)


@pytest.mark.parametrize("name", ["award", "lease", "heartbeat_churn", "sybil"])
def test_member_attack_is_bounded(checks: dict[str, Check], name: str) -> None:
    """bench/attacks_member.py: what a member may do in its own name, a keyless Sybil."""
    check = checks[name]
    assert check.passed, json.dumps(check.figures)
