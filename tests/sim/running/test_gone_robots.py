"""Nothing is recorded for a robot the team declared gone: a robot that falls silent in
the middle of a long operation (its network cut, the simulation not told, as when its
computer hangs) has that operation aborted when the team declares it failed; it is not
credited, its body stays where it was, and the rest of the team finishes the mission."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import anyio
import pytest

import btcap.sim.running.runner
from btcap.actors import TimeSource, handler
from btcap.sim.mission.scenario import Scenario, load_scenario
from btcap.sim.running.hosts import InProcessHost
from btcap.sim.running.runner import run_scenario
from btcap.sim.world.distance import Cell
from btcap.sim.world.grid import GridMap
from btcap.sim.world.manager import SimEvent, SimulationManager
from btcap.sim.world.messages import Operate, SimResult
from btcap.transports import MessageRegistry

pytestmark = pytest.mark.slow

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
VICTIM = "bebop1"
LONG_S = 5_000.0
"""The victim's operation lasts this long (clock s): far past the team's verdict."""


class Hang:
    """Where the test reaches into the run: the host, and what the manager saw."""

    host: InProcessHost | None = None
    manager: SimulationManager | None = None
    frozen_at: float | None = None
    hung: SimEvent | None = None
    position_at_verdict: Cell | None = None


class HangingHost(InProcessHost):
    def __init__(self, s: Scenario, clock: TimeSource, reg: MessageRegistry, grid: GridMap):
        super().__init__(s, clock, reg, grid)
        Hang.host = self


class WatchedManager(SimulationManager):
    """Cuts the victim off the network as it starts its first operation, and makes that
    operation long: without the team's verdict it would complete long after."""

    def on_start(self) -> None:
        super().on_start()
        Hang.manager = self

    @handler
    def on_operate(self, msg: Operate) -> SimResult | asyncio.Future[SimResult]:
        answer = super().on_operate(msg)
        if msg.robot == VICTIM and Hang.frozen_at is None and isinstance(answer, asyncio.Future):
            assert Hang.host is not None
            Hang.host.net.isolate(VICTIM)  # falls silent; the simulation is not told
            Hang.frozen_at = self.now()
            Hang.hung = self.events[-1]
        return answer

    async def _operate(self, r: Any, msg: Operate, duration: float, fails: bool, op: Any) -> None:
        if msg.robot == VICTIM:
            duration, fails = LONG_S, False
        await super()._operate(r, msg, duration, fails, op)

    def team_verdict(self, name: str, gone: bool, *, present: bool = True) -> None:
        super().team_verdict(name, gone, present=present)
        if name == VICTIM and gone:
            Hang.position_at_verdict = self.position(name)


async def test_a_robot_that_hangs_mid_operation_is_credited_nothing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(btcap.sim.running.runner, "SimulationManager", WatchedManager)
    monkeypatch.setattr(Hang, "frozen_at", None)
    monkeypatch.setattr(Hang, "hung", None)
    s = load_scenario(SMALL)
    with anyio.fail_after(60):
        result = await run_scenario(s, host=HangingHost)
    manager = Hang.manager
    hung = Hang.hung
    assert manager is not None
    assert Hang.frozen_at is not None
    assert hung is not None
    assert not result.timed_out
    assert ("failed", VICTIM) in {(m.event, m.robot) for m in result.marks}
    # The operation running when it hung ended unfinished at the verdict, not credited.
    assert (hung.robot, hung.ok, hung.detail) == (VICTIM, False, "declared gone by the team")
    assert hung.end is not None
    assert hung.end - hung.start < LONG_S
    assert not [e for e in manager.events if e.robot == VICTIM and e.start > Hang.frozen_at]
    # Its body stayed where it was when the team gave up on it.
    assert not manager.robots[VICTIM].up
    assert manager.position(VICTIM) == Hang.position_at_verdict
