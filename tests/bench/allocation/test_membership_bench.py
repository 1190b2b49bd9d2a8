"""The membership benchmark's two ways, small and short: with the defaults and 1 % loss,
no false failure, and the dead robot found by all within the stated bound."""

from __future__ import annotations

import asyncio

from btcap.bench.allocation.membership import agent_team, core_team


def test_the_core_over_the_seeded_network() -> None:
    row = core_team(20, 60.0)
    assert row["false_failures"] == 0
    assert row["detect_s"] is not None
    assert row["detect_s"] <= row["bound_s"]
    assert 15 < row["msgs_per_s"] < 30  # a probe and an answer a period, and a little more


def test_full_agents_over_the_in_process_network() -> None:
    row = asyncio.run(asyncio.wait_for(agent_team(6, 10.0), 60))
    assert (row["false_failures"], row["false_while_joining"]) == (0, 0)
    assert row["detect_s"] is not None
    assert row["detect_s"] <= row["bound_s"]
