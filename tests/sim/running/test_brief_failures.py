"""A robot cut off for a moment in the middle of an operation: the simulation (its body)
says the operation stopped, the robot hears it although cut off from its team, and the
work goes on once it is back, not after its leaf's ask timeout (3 h of mission time)."""

from __future__ import annotations

from pathlib import Path

import anyio
import msgspec

from btcap.bench.allocation.missiontime import TEAM_FILE, scenario
from btcap.sim.mission.scenariofile import Event
from btcap.sim.running.runner import run_fast


async def test_a_robot_down_for_seconds_mid_operation_does_not_stall_the_mission(
    tmp_path: Path,
) -> None:
    team = tmp_path / "team.yaml"
    team.write_text(TEAM_FILE)
    s = scenario(5, 1, "auction", team)
    victim = s.robots[2].name
    s = msgspec.structs.replace(s, events=[Event(150.0, victim, "fail", 6.0)])
    with anyio.fail_after(120):
        result = await run_fast(s)
    assert result.completed
    cut = [i for i in result.timeline if i.robot == victim and i.start < 150.0 <= i.end]
    assert cut, "the robot was busy when it failed: the case this test is about"
    # Before: the interrupted operation's failure never reached the robot, which waited
    # out its 3 h ask timeout (mission 11011 s); now about 1000 s.
    assert result.mission_time_s < 2000.0, result.mission_time_s
