"""The hostile-input probe in its quick form, in-process (a few seconds, loopback only)."""

from __future__ import annotations

import asyncio
import json

import pytest

from btcap.bench.attacks.member import probe_members, probe_own_name, probe_sybil
from btcap.bench.attacks.nodes import probe as node_actions
from btcap.bench.attacks.probe import MORE_PROBES, Check, probe

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def checks() -> dict[str, Check]:
    """The original probe; the others run on teams of their own below (and all of them in
    ``python -m btcap.bench attacks``), so each stays well within a test's time limit."""
    # The probe judges by counts (an ask counts as served unless the target stalls for
    # a lease, 3 s), so it passes on a loaded machine; latencies are figures.
    result = asyncio.run(asyncio.wait_for(probe(quick=True, more=False), timeout=60))
    return {c.name: c for c in result}


@pytest.fixture(scope="module")
def node_checks() -> dict[str, Check]:
    result = asyncio.run(asyncio.wait_for(node_actions(True), timeout=40))
    return {name: Check(name, passed, figures) for name, passed, figures in result}


@pytest.fixture(scope="module")
def member_checks() -> dict[str, Check]:
    result = asyncio.run(asyncio.wait_for(probe_own_name(True), timeout=40))
    return {name: Check(name, passed, figures) for name, passed, figures in result}


def test_the_bench_runs_every_probe() -> None:
    assert node_actions in MORE_PROBES
    assert probe_members in MORE_PROBES


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


def test_no_node_action_attack_succeeds(node_checks: dict[str, Check]) -> None:
    """The node-action probe (bench/attacks/nodes.py): five attacks, keyless and with a
    member's CURVE key, each refused and counted."""
    nodes = {name: c for name, c in node_checks.items() if name.startswith("node_")}
    assert len(nodes) == 10
    failed = {name: c.figures for name, c in nodes.items() if not c.passed}
    assert not failed, json.dumps(failed)


def test_a_keyless_sybil_is_forgotten() -> None:
    """bench/attacks/member.py: made-up members with big capability lists, beating 5 s
    then silent, twice, with the default timing: all forgotten, their files, memory and
    idle CPU given back after each flood, no robot falsely failed."""
    ((name, passed, figures),) = asyncio.run(asyncio.wait_for(probe_sybil(True), timeout=120))
    assert name == "sybil"
    assert passed, json.dumps(figures)


@pytest.mark.parametrize("name", ["award", "lease", "heartbeat_churn"])
def test_member_attack_is_bounded(member_checks: dict[str, Check], name: str) -> None:
    """bench/attacks/member.py: what a member may do in its own name."""
    check = member_checks[name]
    assert check.passed, json.dumps(check.figures)
