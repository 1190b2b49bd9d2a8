"""``--distributed``: the same mission with every robot in its own OS process."""

from __future__ import annotations

from pathlib import Path

import anyio
import pytest

from btcap.sim.distributed import ProcessHost, run_distributed
from btcap.sim.scenario import load_scenario

DATA = Path(__file__).resolve().parent / "data"

pytestmark = pytest.mark.slow


async def test_small_mission_completes_with_robots_in_separate_processes() -> None:
    s = load_scenario(DATA / "small.yaml")
    hosts: list[ProcessHost] = []
    real_init = ProcessHost.__init__

    def spy(self: ProcessHost, *args: object, **kwargs: object) -> None:
        real_init(self, *args, **kwargs)  # type: ignore[arg-type]
        hosts.append(self)

    with anyio.fail_after(60):
        mp = pytest.MonkeyPatch()
        mp.setattr(ProcessHost, "__init__", spy)
        try:
            result = await run_distributed(s)
        finally:
            mp.undo()
    assert result.completed
    assert result.summary["found"] == s.objects
    # Every robot ran in a child process, and every child is gone afterwards.
    (host,) = hosts
    assert sorted(host.started) == ["bebop1", "husky1", "spot1"]
    assert all(not p.alive() for p in host.started.values())
    # Work was spread over the team as in-process runs spread it.
    kinds = {(i.robot, i.kind) for i in result.timeline if i.kind != "move" and i.ok}
    assert ("bebop1", "explore") in kinds
    assert any(k == "decontaminate" for _, k in kinds)
