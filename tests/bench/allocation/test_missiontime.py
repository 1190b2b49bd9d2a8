"""The mission-time bench's offline nearest-first reference, on hand-checked instances,
and a short run of the bench itself."""

from __future__ import annotations

import asyncio
import tempfile
from pathlib import Path

import numpy as np
import pytest

from btcap.bench.__main__ import main as bench_main
from btcap.bench.allocation import missiontime
from btcap.bench.allocation.missiontime import TEAM_FILE, Job, nearest_first, reference_of, scenario
from btcap.sim.running.runner import run_fast
from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import OperationModel, RobotModel

# A corridor of 11 cells: start at the left end, the decontamination area at the right.
CORRIDOR = GridMap.from_array(np.ones((1, 11), dtype=bool), start=(0, 0), decon_area=(0, 10))
# h identifies in 10 s and decontaminates in 4 s at 1 m/s; s only identifies, 1 s at 2 m/s.
H = RobotModel(
    cost_factor=2.0,
    speed_mps=1.0,
    identify=OperationModel(10.0),
    decontaminate=OperationModel(4.0),
)
S = RobotModel(cost_factor=1.0, speed_mps=2.0, identify=OperationModel(1.0))


def test_each_free_robot_takes_the_nearest_task_it_can_do() -> None:
    # Listed far first: object 0 at 9 m (clean), 1 at 6 m (clean), 2 at 2 m (contaminated).
    objects = [((0, 9), False), ((0, 6), False), ((0, 2), True)]
    ref = nearest_first(CORRIDOR, [H, S], objects)
    # t=0: both robots 2 m from object 2, the tie goes to h (robot 0): 2 s + 10 s.
    # s takes the nearest left, object 1: 6 m / 2 m/s + 1 s = 4. At 4 it is 3 m from
    # object 0: 1.5 s + 1 s. It cannot decontaminate, so it waits; object 2's
    # Decontaminate is pending when h's Identify ends at 12, and h, there, takes it:
    # carry 8 m at 1 m/s + 4 s = 24.
    assert ref.schedule == (
        Job(0, "identify", 2, 0.0, 12.0),
        Job(1, "identify", 1, 0.0, 4.0),
        Job(1, "identify", 0, 4.0, 6.5),
        Job(0, "decontaminate", 2, 12.0, 24.0),
    )
    assert ref.mission_time_s == 24.0


def test_finish_first_counts_the_faster_robot_as_nearer() -> None:
    objects = [((0, 9), False), ((0, 6), False), ((0, 2), True)]
    ref = nearest_first(CORRIDOR, [H, S], objects, by="finish")
    # t=0: s ends object 2 first (1 s + 1 s); h then ends object 1 soonest (6 + 10 s).
    # At 2 s, s goes on to object 0 (7 m: 3.5 + 1 s); h carries object 2 when it comes
    # free at 16: 4 m back, 8 m on, 4 s. Slower than nearest-first here (32 s, not 24).
    assert ref.schedule == (
        Job(1, "identify", 2, 0.0, 2.0),
        Job(0, "identify", 1, 0.0, 16.0),
        Job(1, "identify", 0, 2.0, 6.5),
        Job(0, "decontaminate", 2, 16.0, 32.0),
    )
    assert ref.mission_time_s == 32.0


def test_robots_start_where_they_are_told() -> None:
    # s starts at the right end: 1 m from object 0; h at the left, 2 m from object 1.
    ref = nearest_first(CORRIDOR, [H, S], [((0, 9), False), ((0, 2), False)], at=[(0, 0), (0, 10)])
    assert ref.schedule == (Job(1, "identify", 0, 0.0, 1.5), Job(0, "identify", 1, 0.0, 12.0))


def test_a_task_no_robot_can_do_is_refused() -> None:
    with pytest.raises(ValueError, match="object 0: no robot can decontaminate"):
        nearest_first(CORRIDOR, [S], [((0, 3), True)])


def test_the_reference_times_a_task_as_the_simulator_does() -> None:
    # One husky, one contaminated object: no choice, so the real mission differs from the
    # reference only by its start (the first Explore and auction) and the 0.5 s steps.
    with tempfile.TemporaryDirectory() as tmp:
        team = Path(tmp) / "team.yaml"
        team.write_text(TEAM_FILE)
        seed = next(
            seed
            for seed in range(1, 50)
            if reference_of(scenario(1, seed, "optimal", team, objects=1)).schedule[-1].kind
            == "decontaminate"
        )
        s = scenario(1, seed, "optimal", team, objects=1)
        ref = reference_of(s)
        real = asyncio.run(asyncio.wait_for(run_fast(s), 60))
    assert real.completed
    assert ref.mission_time_s > 100  # a drive, 60 s, a carry and 8 s
    assert 0 <= real.mission_time_s - ref.mission_time_s <= 5


def test_the_bench_compares_strategies_with_the_reference_and_sequential(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    written: dict[str, object] = {}
    monkeypatch.setattr(missiontime, "write_result", lambda name, data: written.update(data))
    argv = ["missiontime", "--quick", "--robots", "3", "--seeds", "1"]
    assert bench_main([*argv, "--strategies", "sequential,optimal,optimal+queue"]) == 0
    assert written["not_completed"] == {"3": {"sequential": 0, "optimal": 0, "optimal+queue": 0}}
    assert written["vs_sequential"]["3"]["sequential"] == {"mean": 1.0, "max": 1.0}  # type: ignore[index]
    for name in ("optimal", "optimal+queue"):
        ratio = written["vs_reference"]["3"][name]  # type: ignore[index]
        assert 0.5 < ratio["mean"] <= ratio["max"] < 3
    target = written["target"]
    assert target["strategy"] == "optimal"  # type: ignore[index]
    assert isinstance(target["met"], bool)  # type: ignore[index]
    out = capsys.readouterr().out
    assert "load average" in out
    assert "target (default optimal" in out


def test_the_bench_names_a_bad_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        missiontime.main(["--strategies", "fastest"])
    assert "--strategies: fastest; expected some of" in capsys.readouterr().err
