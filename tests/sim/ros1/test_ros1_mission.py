"""The simulator behind ROS 1 as the paper set it up (a move_base action server per robot,
the operations as services), with a real rosmaster and rospy processes: the paper's mission
ends as the direct simulation does, and a capability goes to the robot whose servers are
still there when the other one's left the ROS graph. Nothing is left running."""

from __future__ import annotations

import time
from collections import Counter

import anyio
import pytest
from simros1 import WHY_NOT, children, loopback
from structlog.testing import capture_logs

from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.scenario import Scenario, load_scenario
from btcap.sim.mission.scenariofile import ScenarioRos
from btcap.sim.ros1 import host as ros1_host
from btcap.sim.running.metrics import MissionResult
from btcap.sim.running.runner import run_fast, run_scenario

pytestmark = [
    pytest.mark.ros1,
    pytest.mark.skipif(WHY_NOT is not None, reason=str(WHY_NOT)),
    pytest.mark.slow,
    pytest.mark.usefixtures("loopback"),
    pytest.mark.timeout(400),  # a bound: each mission takes about a minute of wall time here
]

__all__ = ["loopback"]  # the fixture, used by every test here

#: What a mission's outcome is, in its summary: the same over ROS 1 as directly.
OUTCOME = ("objects", "found", "identified", "contaminated", "decontaminated", "coverage")


def full_team() -> Scenario:
    return load_scenario(builtin_scenarios()["full-team"])  # speed-up 100, wall clock


def served_of(logs: list[dict[str, object]]) -> dict[str, dict[str, int]]:
    (served,) = [e["goals"] for e in logs if e["event"] == "sim.ros1_served"]
    assert isinstance(served, dict)
    return served


def check_outcome(over: MissionResult, direct: MissionResult) -> None:
    assert direct.completed, direct.summary
    assert over.completed, over.summary
    assert not over.errors
    assert not over.timed_out
    assert {k: over.summary[k] for k in OUTCOME} == {k: direct.summary[k] for k in OUTCOME}
    assert over.summary["decontaminated"] == over.summary["contaminated"] > 0


async def test_the_full_mission_over_ros1_ends_as_the_direct_simulation() -> None:
    with anyio.fail_after(300):
        direct = await run_fast(full_team())
        with capture_logs() as logs:
            over = await run_scenario(full_team(), ros1=True)
    check_outcome(over, direct)
    # Every move and operation came to the simulation through the robot's move_base or
    # its operation's service (a move to where a robot already is leaves no line).
    served = served_of(logs)
    assert set(served) == {"husky1", "spot1", "bebop1"}
    for robot, goals in served.items():
        lines = Counter(i.kind for i in over.timeline if i.robot == robot)
        ops = {k: n for k, n in goals.items() if k != "move_base"}
        assert ops == {k: n for k, n in lines.items() if k != "move"}, robot
        assert goals.get("move_base", 0) >= lines["move"] > 0, robot
    assert [e for e in logs if e["event"] == "sim.ros1_master"]  # it started its own
    assert children() == []  # the master, the servers' and the robots' rospy processes


class _Withdrawing(ros1_host.Ros1Host):
    """The real host, whose bebop1 loses its servers once the team is up and before the
    mission starts (its agent lives on): explore is then auctioned between husky1, whose
    servers are there, and bebop1, whose are gone."""

    async def __aenter__(self) -> _Withdrawing:
        await super().__aenter__()
        started = self.started
        assert started is not None
        assert started.servers is not None
        assert started.links is not None
        link = started.links.links["bebop1"]
        assert link.missing() == []
        started.servers.withdraw("bebop1")

        def gone() -> bool:  # the bridge's poller saw both leave the master
            while len(link.missing()) < 2:
                anyio.from_thread.check_cancelled()
                time.sleep(0.02)
            return True

        assert await anyio.to_thread.run_sync(gone, abandon_on_cancel=True)
        return self


async def test_a_capability_goes_to_the_namespaced_robot_that_keeps_its_server(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(ros1_host, "Ros1Host", _Withdrawing)
    s = full_team()
    s.ros = ScenarioRos(backend="ros1", namespace="/team/{robot}")
    with anyio.fail_after(300):
        direct = await run_fast(full_team())
        with capture_logs() as logs:
            over = await run_scenario(s, ros1=True)
    check_outcome(over, direct)
    explored = Counter(i.robot for i in over.timeline if i.kind == "explore")
    assert set(explored) == {"husky1"}, explored
    served = served_of(logs)
    assert "explore" not in served["bebop1"]
    assert "move_base" not in served["bebop1"]
    assert served["husky1"]["explore"] == explored["husky1"]
    # In the direct run bebop1, the faster explorer, takes exploration.
    assert {i.robot for i in direct.timeline if i.kind == "explore"} == {"bebop1"}
    assert children() == []
