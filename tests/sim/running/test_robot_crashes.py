"""A robot whose runtime crashes is reported, never dropped: logged with its name, listed
in the mission result's ``errors`` and in the summary, taken out of the simulation, and the
rest of the team finishes the mission."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import anyio
import msgspec
import pytest
from rich.console import Console

import btcap.sim.running.hosts
from btcap.actors import Supervision, handler
from btcap.sim.mission.capabilities import RobotSetup, robot_setup
from btcap.sim.mission.scenario import Scenario, load_scenario
from btcap.sim.running.metrics import MissionResult
from btcap.sim.running.runner import run_scenario
from btcap.sim.running.runview import summary_table
from btcap.sim.world.grid import GridMap
from btcap.sim.world.messages import PositionUpdate
from btcap.sim.world.model import RobotModel
from btcap.sim.world.robot import Body

pytestmark = pytest.mark.slow

DYNAMIC = Path(__file__).parents[1] / "data" / "dynamic.yaml"


def two_huskies_and_a_bebop() -> Scenario:
    """husky1, husky2 and bebop1 from the start, no scheduled event: either Husky can do
    every task, so the mission can finish without one of them."""
    return msgspec.structs.replace(load_scenario(DYNAMIC), events=[])


class FragileBody(Body):
    """Breaks at the first position report, escalating to its actor system."""

    supervision = Supervision.ESCALATE

    @handler
    def on_position(self, msg: PositionUpdate) -> None:
        raise RuntimeError("wheel fell off")


def patch_setup(monkeypatch: pytest.MonkeyPatch, robot: str, change: Any) -> None:
    """Let ``change(setup, grid)`` alter what ``robot`` brings to its agent."""

    def setup(name: str, model: RobotModel, grid: GridMap, **kw: Any) -> RobotSetup:
        made = robot_setup(name, model, grid, **kw)
        return change(made, grid) if name == robot else made

    monkeypatch.setattr(btcap.sim.running.hosts, "robot_setup", setup)


def fragile(made: RobotSetup, grid: GridMap) -> RobotSetup:
    made.actors[Body.PATH] = FragileBody("husky1", grid.start)
    return made


def no_battery(made: RobotSetup, grid: GridMap) -> RobotSetup:
    raise RuntimeError("no battery")


def assert_reported(result: MissionResult, robot: str, *fragments: str) -> None:
    assert [e.robot for e in result.errors] == [robot], result.errors
    for fragment in fragments:
        assert fragment in result.errors[0].error
    decoded = msgspec.json.decode(result.to_json(), type=MissionResult)
    assert decoded.errors == result.errors
    text = render(result)
    assert "robot errors" in text
    assert robot in text
    assert fragments[-1] in text


def render(result: MissionResult) -> str:
    out = io.StringIO()
    Console(file=out, width=200).print(summary_table([result]))
    return out.getvalue()


async def test_an_actor_crash_mid_mission_is_reported_and_the_team_finishes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    patch_setup(monkeypatch, "husky1", fragile)
    with anyio.fail_after(30):
        result = await run_scenario(two_huskies_and_a_bebop())
    assert_reported(result, "husky1", "escalated", "wheel fell off")
    assert result.completed
    assert not result.timed_out
    crashed = next(m.time for m in result.marks if (m.event, m.robot) == ("crashed", "husky1"))
    assert crashed == result.errors[0].time
    # Out of the simulation from then on: none of its work goes on past the crash.
    for iv in result.timeline:
        if iv.robot == "husky1":
            assert iv.end <= crashed + 1.0, iv
    assert result.robots["husky2"].tasks.get("decontaminate", 0) > 0


async def test_a_robot_that_cannot_start_is_reported_and_not_waited_for(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    patch_setup(monkeypatch, "bebop1", no_battery)
    with anyio.fail_after(30):  # far below the minute the team has to form
        result = await run_scenario(two_huskies_and_a_bebop())
    assert_reported(result, "bebop1", "RuntimeError: no battery")
    assert result.completed
    assert result.robots["bebop1"].tasks == {}
