"""``btcap run``: writes a JSON result and a timeline plot; usage errors exit 2, cleanly."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import msgspec
import pytest

import btcap.cli
from btcap.cli import main
from btcap.sim.mission.scenario import ScenarioError, grow_team, resolve_scenario
from btcap.sim.running.metrics import MissionResult

SMALL = Path(__file__).parents[1] / "data" / "small.yaml"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: Wall seconds the crowd test waits for its calm run's process (a hang bound).
CALM_S = 600.0


@pytest.fixture(autouse=True)
def no_logging_setup(monkeypatch: pytest.MonkeyPatch) -> None:
    """main() configures structlog globally, onto this test's captured stderr: later
    tests would log into a closed file. Keep the configuration as it is."""
    monkeypatch.setattr(btcap.cli, "configure_logging", lambda level, json=False: None)


def usage_error(capsys: pytest.CaptureFixture[str], argv: list[str], *fragments: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("btcap: error: ")
    assert err.count("\n") == 1, err  # one line
    for fragment in fragments:
        assert fragment in err, err


@pytest.mark.slow
def test_run_writes_result_and_timeline(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    assert main(["run", str(SMALL), "--out", str(out), "--quiet"]) == 0
    result = msgspec.json.decode((out / "result.json").read_bytes(), type=MissionResult)
    assert result.scenario == "small"
    assert result.completed
    assert set(result.robots) == {"husky1", "spot1", "bebop1"}
    assert result.timeline
    png = (out / "timeline.png").read_bytes()
    assert png.startswith(PNG_MAGIC)
    assert len(png) > 10_000
    printed = capsys.readouterr().out
    assert "mission summary" in printed
    assert str(out) in printed.replace("\n", "")


def test_unknown_scenario_name(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    usage_error(
        capsys,
        ["run", "no-such-scenario", "--out", str(tmp_path), "--quiet"],
        "no-such-scenario",
        "full-team",
    )
    assert not list(tmp_path.iterdir())


def test_invalid_scenario_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nrobots: [{name: r, model: tank}]\n")
    argv = ["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"]
    usage_error(capsys, argv, str(bad), "robots[0].model", "'tank'")
    assert not (tmp_path / "o").exists()


SMALL_MAP = "map: {cave: {width: 50, height: 35, seed: 3}}"


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("objects: 4", "objects: 100000", "objects"),  # more than the cave's cells
        (SMALL_MAP, "map: {cave: {width: 100000, height: 100000}}", "map.cave"),
        (SMALL_MAP, "map: {cave: {width: 40000, height: 40000}}", "map.cave"),  # memory
        ("objects: 4", "objects: -1", "objects"),
        ("seed: 4", "seed: -4", "seed"),
        ("speedup: 1000", "speedup: 0", "speedup"),
        ("speedup: 1000", "speedup: .inf", "speedup"),
        ("time_limit_s: 20000", "time_limit_s: -1", "time_limit_s"),
        ("{step_s: 1.0,", "{step_s: 0,", "sim.step_s"),
        ("tick_hz: 1.0", "tick_hz: .nan", "agent.tick_hz"),
        ("{name: spot1, model: spot}", "{name: spot1, model: tank}", "robots[1].model"),
        (
            "robots:\n  - {name: husky1, model: husky}\n  - {name: spot1, model: spot}\n"
            "  - {name: bebop1, model: bebop}\n",
            "robots: []\n",
            "robots",
        ),
        ("name: small", "name: ..", "name"),
    ],
)
def test_an_impossible_scenario_is_one_line_naming_file_and_field(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, old: str, new: str, field: str
) -> None:
    text = SMALL.read_text()
    assert old in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace(old, new))
    argv = ["run", str(bad), "--fast", "--out", str(tmp_path / "o"), "--quiet"]
    usage_error(capsys, argv, f"btcap: error: {bad}: {field}: ")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("speedup", ["0", "-5", "nan", "inf"])
def test_speedup_must_be_positive(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, speedup: str
) -> None:
    argv = ["run", str(SMALL), f"--speedup={speedup}", "--out", str(tmp_path / "o"), "--quiet"]
    usage_error(capsys, argv, "--speedup")
    assert not (tmp_path / "o").exists()


def test_resolve_scenario() -> None:
    assert resolve_scenario("single-husky").name == "single-husky"
    assert resolve_scenario(str(SMALL)).name == "small"
    with pytest.raises(ScenarioError, match="not a built-in"):
        resolve_scenario("nowhere.yaml")


def test_run_is_a_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--help"]) == 0
    assert "--speedup" in capsys.readouterr().out


@pytest.mark.parametrize("margin", ["0", "1", "-0.2", "nan"])
def test_rebid_margin_must_be_a_fraction(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, margin: str
) -> None:
    argv = ["run", str(SMALL), f"--rebid-on-join={margin}", "--out", str(tmp_path / "o")]
    usage_error(capsys, argv, "--rebid-on-join", "(0, 1)")
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_allocation_policies_from_the_command_line(tmp_path: Path) -> None:
    # The dynamic test scenario without its failure: husky1 is exploring, healthy, when
    # the Bebop joins; only the command-line policy moves that work.
    text = (SMALL.parent / "dynamic.yaml").read_text()
    scenario = tmp_path / "joins.yaml"
    scenario.write_text(
        text.replace("  - {at: 20, robot: husky1, kind: fail, duration: 200}\n", "")
    )
    out = tmp_path / "out"
    argv = ["run", str(scenario), "--rebid-on-join", "0.25", "--queue-after-current"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    result = msgspec.json.decode((out / "result.json").read_bytes(), type=MissionResult)
    assert result.completed
    assert result.moved >= 1


@pytest.mark.parametrize("extra", [["--distributed"], ["--speedup", "5"]])
def test_fast_mode_is_one_process_on_virtual_time(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, extra: list[str]
) -> None:
    argv = ["run", str(SMALL), "--fast", *extra, "--out", str(tmp_path / "o"), "--quiet"]
    usage_error(capsys, argv, "--fast")
    assert not (tmp_path / "o").exists()


def test_fast_mode_writes_the_same_result_twice(small_fast_twice: tuple[Path, Path]) -> None:
    first, second = ((out / "result.json").read_bytes() for out in small_fast_twice)
    assert first == second
    assert msgspec.json.decode(first, type=MissionResult).completed


def _crowd(path: Path, robots: int) -> Path:
    """A small cave with more robots than any built-in scenario and the default protocol
    timing (short timeouts, so a timer decided by wall time would show)."""
    models = ("husky", "spot", "bebop")
    team = "".join(f"  - {{name: r{i}, model: {models[i % 3]}}}\n" for i in range(robots))
    path.write_text(
        "name: crowd\nseed: 4\nobjects: 8\ncontaminated_share: 0.5\ntime_limit_s: 600\n"
        "map: {cave: {width: 50, height: 35, seed: 3}}\n"
        "sim: {step_s: 1.0, delay_jitter: 0.2, failure_chance: 0.05}\n"
        f"robots:\n{team}"
    )
    return path


@pytest.mark.slow
def test_fast_mode_with_a_crowd_writes_the_same_result_however_loaded_the_machine(
    tmp_path: Path,
) -> None:
    """Every timer of a virtual-time run is on the virtual clock: a thread burning CPU
    alongside (it takes the GIL from the event loop at instants that differ from run to
    run, and slows it down) changes nothing. The calm run is another process's (``btcap
    run``, started first), made while this one runs beside the thread."""
    scenario = _crowd(tmp_path / "crowd.yaml", 30)

    def argv(out: str) -> list[str]:
        return ["run", str(scenario), "--fast", "--no-record", "--out", str(tmp_path / out)]

    errors = tmp_path / "calm.err"
    with errors.open("wb") as err:  # a file, not a pipe: the process never waits for us
        calm = subprocess.Popen(
            [sys.executable, "-m", "btcap", *argv("calm"), "--quiet"],
            stdout=subprocess.DEVNULL,
            stderr=err,
        )
    stop = threading.Event()

    def burn() -> None:
        n = 0
        while not stop.is_set():
            n += 1

    burner = threading.Thread(target=burn, daemon=True)
    burner.start()
    try:
        assert main([*argv("loaded"), "--quiet"]) == 0
    finally:
        stop.set()
        burner.join(timeout=10)
        try:
            calm.wait(timeout=CALM_S)  # a hang bound, not a speed measure
        finally:
            calm.kill()  # no-op once it ended
            calm.wait()
    assert not burner.is_alive()
    assert calm.returncode == 0, errors.read_text()
    first = (tmp_path / "calm" / "result.json").read_bytes()
    assert first == (tmp_path / "loaded" / "result.json").read_bytes()
    result = msgspec.json.decode(first, type=MissionResult)
    assert len(result.robots) == 30
    assert result.completed


def test_robots_grows_the_team_by_its_models_and_refuses_to_shrink_it(tmp_path: Path) -> None:
    s = resolve_scenario("full-team")
    grow_team(s, 8)
    assert [r.name for r in s.robots] == [
        "husky1", "spot1", "bebop1", "husky2", "spot2", "bebop2", "husky3", "spot3",
    ]  # fmt: skip
    assert [r.model for r in s.robots[3:]] == ["husky", "spot", "bebop", "husky", "spot"]
    with pytest.raises(ValueError, match="expected at least the scenario's 8 robots"):
        grow_team(s, 2)


@pytest.mark.slow
def test_a_grown_team_never_flaps(tmp_path: Path) -> None:
    """``--robots``: forty robots with the scenario's timing; nobody is failed (the team
    does not flap however large). That a crowd runs the same to the byte twice is the
    crowd test's (above: thirty robots, one run beside a thread taking the CPU), so one
    forty-robot run is enough here."""
    argv = ["run", "full-team", "--robots", "40", "--fast", "--no-record", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 0
    result = msgspec.json.decode((tmp_path / "a" / "result.json").read_bytes(), type=MissionResult)
    assert len(result.robots) == 40
    assert (result.completed, result.robot_failures, result.executions_lost) == (True, 0, 0)


@pytest.mark.slow
def test_a_grown_team_is_told_why_robots_ran_nothing_and_object_workers_grows_the_tree(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--robots 12`` grows the team, not the mission tree (one Explore loop and the
    scenario's 2 object loops): the run says which robots ran nothing and why, and
    ``--object-workers`` gives more of them work."""

    def run(*flags: str) -> tuple[MissionResult, str]:
        out = tmp_path / "-".join(flags)
        argv = ["run", "full-team", "--robots", "12", "--fast", "--no-record", "--quiet"]
        assert main([*argv, *flags, "--out", str(out)]) == 0
        said = capsys.readouterr().out
        return msgspec.json.decode((out / "result.json").read_bytes(), type=MissionResult), said

    def idle(result: MissionResult) -> list[str]:
        return [r for r, st in result.robots.items() if not any(st.tasks.values())]

    grown, said = run()
    assert len(idle(grown)) == 5
    assert (
        "full-team: 5 of 12 robots ran no task (spot3, bebop3, husky4, spot4, "
        "bebop4): the mission tree runs one Explore loop and 2 identify-and-decontaminate "
        "loops (object_workers), at most 3 capabilities at once; --object-workers N runs "
        "more identify-and-decontaminate loops"
    ) in said
    wider, _ = run("--object-workers", "8")
    assert set(idle(wider)) < set(idle(grown))
    assert wider.mission_time_s < grown.mission_time_s
    usage_error(capsys, ["run", "--object-workers", "0"], "--object-workers: expected 1 to 1000")


def test_ros2_is_refused_with_fast_or_distributed_and_without_ros(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--ros2`` runs on the wall clock in this process; where rclpy or the simulated
    robots' interfaces are missing it says how to get them, in one line, before any run."""
    out = str(tmp_path / "out")
    for flag in ("--fast", "--distributed"):
        usage_error(capsys, ["run", "--ros2", flag, "--out", out], "--ros2", "not with --fast")
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "rclpy" else real(name, *a)
    )
    usage_error(capsys, ["run", "--ros2", "--out", out], "rclpy", "make ros-sim", ".venv-ros")
    assert not (tmp_path / "out" / "result.json").exists()
