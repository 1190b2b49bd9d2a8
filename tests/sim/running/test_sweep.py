"""``btcap sweep``: seeds in the fast mode, in-process or on worker processes, give the same
``sweep.json``; the table, the plot and clear usage errors."""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
from sidework import AHEAD

import btcap.cli
from btcap.cli import main
from btcap.sim.mission.scenario import Allocation
from btcap.sim.running.metrics import MissionResult, RobotStats
from btcap.sim.running.sweep import RunFigures, Spread, SweepResult

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
HAS_STRATEGY = any(f.name == "strategy" for f in msgspec.structs.fields(Allocation))


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() configures structlog globally, onto this test's captured stderr: later
    tests would log into a closed file. Keep the configuration as it is."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


@pytest.fixture(autouse=True)
def no_leftover_processes() -> Iterator[None]:
    yield
    # (the suite's side worker, tests/sidework.py, is not the sweep's: it ends with the
    # modules that use it, which may run after this one)
    assert [p for p in multiprocessing.active_children() if p.pid not in AHEAD.pids()] == []


def sweep(out: Path, *extra: str) -> SweepResult:
    assert main(["sweep", str(SMALL), "--out", str(out), *extra]) == 0
    return msgspec.json.decode((out / "sweep.json").read_bytes(), type=SweepResult)


def usage_error(capsys: pytest.CaptureFixture[str], argv: list[str], *fragments: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("btcap: error: "), err
    for fragment in fragments:
        assert fragment in err, err


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_in_process_and_worker_processes_agree(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    one = sweep(tmp_path / "one", "--seeds", "2", "--jobs", "1")
    printed = capsys.readouterr().out
    two = sweep(tmp_path / "two", "--seeds", "2", "--jobs", "2")
    assert (tmp_path / "one" / "sweep.json").read_bytes() == (
        tmp_path / "two" / "sweep.json"
    ).read_bytes()
    assert one == two
    assert one.scenario == "small"
    assert one.seeds == [1, 2]
    [config] = one.configurations
    assert config.reevaluate_s == 30.0
    assert [r.seed for r in config.runs] == [1, 2]
    assert all(r.completed for r in config.runs)
    # The seed reaches the mission: the two runs differ.
    assert config.runs[0].mission_time_s != config.runs[1].mission_time_s
    times = [r.mission_time_s for r in config.runs]
    assert config.stats["mission_time_s"].min == min(times)
    assert config.stats["mission_time_s"].max == max(times)
    assert set(config.stats) == {
        "mission_time_s",
        "idle_s",
        "distance_m",
        "auctions",
        "reassigned",
        "moved",
    }
    for label in (config.name, "mission time [s]", "idle time", "distance [m]", "auctions"):
        assert label in printed, printed
    for folder in ("one", "two"):
        png = (tmp_path / folder / "sweep.png").read_bytes()
        assert png.startswith(PNG_MAGIC)
        assert len(png) > 10_000


@pytest.mark.timeout(60)
def test_no_reevaluate_is_its_own_configuration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result = sweep(tmp_path, "--seeds", "1", "--no-reevaluate", "--jobs", "1")
    [config] = result.configurations
    assert config.reevaluate_s is None
    assert "no re-eval" in config.name
    assert config.stats["mission_time_s"].std is None  # one seed has no spread
    assert config.name in capsys.readouterr().out


@pytest.mark.skipif(not HAS_STRATEGY, reason="the allocation block has no strategy yet")
@pytest.mark.timeout(60)
def test_one_configuration_per_strategy(tmp_path: Path) -> None:
    result = sweep(tmp_path, "--seeds", "1", "--jobs", "1", "--strategy", "arrival", "auction")
    assert [c.strategy for c in result.configurations] == ["arrival", "auction"]
    assert [c.name for c in result.configurations] == [
        "arrival, re-eval 30 s",
        "auction, re-eval 30 s",
    ]


@pytest.mark.skipif(not HAS_STRATEGY, reason="the allocation block has no strategy yet")
def test_unknown_strategy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "o"
    argv = ["sweep", str(SMALL), "--seeds", "2", "--strategy", "bogus", "--out", str(out)]
    usage_error(capsys, argv, "--strategy", "allocation.strategy", "'bogus'", "auction")
    assert not out.exists()


@pytest.mark.skipif(HAS_STRATEGY, reason="the allocation block has a strategy")
def test_strategy_without_a_strategy_field(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["sweep", str(SMALL), "--seeds", "2", "--strategy", "auction", "--out", str(tmp_path)]
    usage_error(capsys, argv, "--strategy", "no allocation strategy", "reevaluate_s")


@pytest.mark.parametrize(
    ("extra", "fragments"),
    [
        (["--seeds", "0"], ["--seeds", "got 0"]),
        (["--seeds", "-3"], ["--seeds", "got -3"]),
        (["--seeds", "2", "--jobs", "0"], ["--jobs", "got 0"]),
    ],
)
def test_bad_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], fragments: list[str]
) -> None:
    usage_error(capsys, ["sweep", str(SMALL), *extra, "--out", str(tmp_path / "o")], *fragments)
    assert not (tmp_path / "o").exists()


def test_unknown_scenario(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["sweep", "no-such-scenario", "--seeds", "2", "--out", str(tmp_path / "o")]
    usage_error(capsys, argv, "no-such-scenario", "full-team")
    assert not (tmp_path / "o").exists()


def test_out_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    file = tmp_path / "taken"
    file.write_text("x")
    usage_error(capsys, ["sweep", str(SMALL), "--seeds", "2", "--out", str(file)], str(file))
    usage_error(
        capsys,
        ["sweep", str(SMALL), "--seeds", "2", "--out", str(file / "below")],
        "cannot create",
    )
    assert file.read_text() == "x"


def test_figures_of_a_run() -> None:
    def stats(present: float, busy: float, distance: float) -> RobotStats:
        return RobotStats("husky", busy, present, busy / present if present else 0.0, {}, distance)

    result = MissionResult(
        scenario="s",
        completed=True,
        mission_time_s=100.0,
        summary={},
        # a: idle 40 s; b: busier than present (rounding) counts 0; c never took part.
        robots={"a": stats(100, 60, 10), "b": stats(50, 50.5, 5), "c": stats(0, 0, 0)},
        auctions=7,
        executions_lost=1,
        reassigned=1,
        robot_failures=0,
        robots_left=0,
        assignments={},
        timeline=[],
        marks=[],
        moved=2,
    )
    assert RunFigures.of(3, result) == RunFigures(3, True, 100.0, 20.0, 15.0, 7, 1, 2)


def test_spread() -> None:
    assert Spread.of([1.0, 2.0, 3.0]) == Spread(2.0, 1.0, 1.0, 3.0)
    assert Spread.of([5.0]) == Spread(5.0, None, 5.0, 5.0)
