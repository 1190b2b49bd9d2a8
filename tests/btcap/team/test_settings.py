"""One settings schema: code, agent files and scenarios get the same bounds, relations and
defaults (the scenario's own timing defaults aside), and a bad value names its field."""

from __future__ import annotations

import re
from typing import Any

import msgspec
import pytest

from btcap.sim.mission.scenario import AgentTiming
from btcap.sim.mission.scenario import Allocation as ScenarioAllocation
from btcap.team.deployment.agentconfig import Allocation as FileAllocation
from btcap.team.deployment.agentconfig import FileTiming
from btcap.team.deployment.agentspec import AgentSpec, agent_config
from btcap.team.membership.membership import Membership
from btcap.team.settings import AgentConfig, Allocation, MissionConfig, Timing


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"tick_hz": 0}, "tick_hz: Expected `float` > 0.0"),
        ({"heartbeat_s": -1.0}, "heartbeat_s: Expected `float` > 0.0"),
        ({"heartbeat_s": float("nan")}, "heartbeat_s: Expected `float` > 0.0"),
        ({"heartbeat_fanout": 0}, "heartbeat_fanout: Expected `int` >= 1"),
        ({"move_margin": 1.0}, "move_margin: Expected `float` < 1.0"),
        ({"rebid_on_join": 0.0}, "rebid_on_join: Expected `float` > 0.0"),
        ({"reevaluate_s": 0.0}, "reevaluate_s: Expected `float` > 0.0"),
        ({"strategy": ""}, "strategy: Expected `str` of length >= 1"),
        ({"heartbeat_s": 1.0, "failure_timeout_s": 1.0}, "failure_timeout_s: must exceed"),
        ({"lease_s": 1.0, "keepalive_s": 1.0}, "keepalive_s: must be below lease_s"),
    ],
)
def test_settings_built_in_python_are_checked_as_files_are(
    kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=f"^{re.escape(message)}"):
        AgentConfig(**kwargs)


def test_mission_config_checks_the_leases_it_holds() -> None:
    with pytest.raises(ValueError, match="keepalive_s: must be below lease_s"):
        MissionConfig(lease_s=0.5, keepalive_s=0.6)
    with pytest.raises(ValueError, match="award_timeout_s"):
        MissionConfig(award_timeout_s=0)
    with pytest.raises(TypeError, match="tick_rate"):
        AgentConfig(tick_rate=5.0)  # type: ignore[call-arg]


def test_a_change_keeps_the_checks() -> None:
    cfg = AgentConfig()
    with pytest.raises(ValueError, match="failure_timeout_s: must exceed heartbeat_s"):
        msgspec.structs.replace(cfg, heartbeat_s=1.0)
    assert msgspec.structs.replace(cfg, heartbeat_s=0.2).heartbeat_s == 0.2


def test_the_code_defaults_are_the_library_defaults_of_the_blocks() -> None:
    assert AgentConfig.of(Timing(), Allocation()) == AgentConfig()
    assert AgentConfig.of(FileTiming(), FileAllocation()) == AgentConfig()
    cfg = AgentConfig()
    assert (cfg.tick_hz, cfg.heartbeat_s, cfg.failure_timeout_s, cfg.heartbeat_fanout) == (
        10.0,
        0.1,
        0.5,
        8,
    )
    assert (cfg.lease_s, cfg.keepalive_s, cfg.auction_window_s, cfg.award_timeout_s) == (
        0.8,
        0.2,
        1.0,
        0.5,
    )
    assert (cfg.reevaluate_s, cfg.move_margin, cfg.strategy) == (30.0, 0.2, "optimal")
    assert (cfg.rebid_on_join, cfg.queue_after_current) == (None, False)


def test_a_scenario_keeps_its_simulated_timing_defaults_and_the_same_checks() -> None:
    sim = AgentConfig.of(AgentTiming(), ScenarioAllocation())
    assert (sim.tick_hz, sim.heartbeat_s, sim.failure_timeout_s, sim.lease_s) == (
        2.0,
        2.0,
        15.0,
        20.0,
    )
    assert (sim.keepalive_s, sim.auction_window_s, sim.award_timeout_s) == (2.0, 5.0, 10.0)
    assert sim.heartbeat_fanout == AgentConfig().heartbeat_fanout
    assert ScenarioAllocation is Allocation
    with pytest.raises(ValueError, match="failure_timeout_s: must exceed heartbeat_s"):
        AgentTiming(heartbeat_s=15.0)


def test_a_block_names_the_field_that_broke_a_relation_when_decoded() -> None:
    with pytest.raises(msgspec.ValidationError, match=r"keepalive_s: must be below lease_s"):
        msgspec.convert({"lease_s": 0.1}, Timing)
    with pytest.raises(msgspec.ValidationError, match="unknown field `speedup`"):
        msgspec.convert({"speedup": 2.0}, Timing)


def test_an_agent_spec_config_is_decoded_with_its_field_named() -> None:
    assert agent_config(AgentSpec("r1", config={"tick_hz": 5})) == AgentConfig(tick_hz=5.0)
    with pytest.raises(ValueError, match=r"agent spec 'r1': config: lease_s: Expected `float`"):
        agent_config(AgentSpec("r1", config={"lease_s": "long"}))
    with pytest.raises(ValueError, match=r"config: failure_timeout_s: must exceed heartbeat_s"):
        agent_config(AgentSpec("r1", config={"failure_timeout_s": 0.05}))
    with pytest.raises(ValueError, match=r"config: Object contains unknown field `tick_hzz`"):
        agent_config(AgentSpec("r1", config={"tick_hzz": 5.0}))


def test_membership_takes_its_defaults_and_checks_from_the_settings() -> None:
    m = Membership("me")
    t = Timing()
    assert (m.heartbeat_s, m.failure_timeout_s, m.fanout) == (
        t.heartbeat_s,
        t.failure_timeout_s,
        t.heartbeat_fanout,
    )
    with pytest.raises(ValueError, match="heartbeat_fanout: Expected `int` >= 1"):
        Membership("me", fanout=0)


def test_max_lease_s_bounds_the_leases_a_robot_accepts_and_covers_its_own() -> None:
    assert AgentConfig().max_lease_s == Allocation().max_lease_s == 300.0
    with pytest.raises(ValueError, match=r"^max_lease_s: must not be below lease_s"):
        AgentConfig(lease_s=10.0, keepalive_s=1.0, max_lease_s=5.0)
    with pytest.raises(ValueError, match=r"^max_lease_s: Expected `float` > 0\.0"):
        Allocation(max_lease_s=0.0)
    assert AgentConfig.of(Timing(), Allocation(max_lease_s=2.0)).max_lease_s == 2.0
