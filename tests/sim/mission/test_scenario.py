"""Scenario and team files: the built-ins load; bad files are rejected naming file and field."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from btcap.sim import GridMap
from btcap.sim.mission.scenario import (
    CaveSpec,
    Event,
    MapSpec,
    RobotEntry,
    Scenario,
    ScenarioError,
    builtin_scenarios,
    check_scenario,
    load_scenario,
)
from btcap.sim.world.model import TeamFileError, load_team, paper_team

GOOD = """\
name: test
seed: 3
objects: 4
speedup: 500
map: {cave: {width: 30, height: 20, seed: 2}}
robots:
  - {name: husky1, model: husky}
  - {name: bebop1, model: bebop}
"""


def write(tmp_path: Path, text: str, name: str = "scenario.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def rejected(path: Path, *fragments: str) -> ScenarioError:
    """Loading ``path`` fails with a message naming the file and every fragment."""
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    return info.value


# -- the built-ins ---------------------------------------------------------------------------


def test_the_papers_three_scenarios_are_built_in() -> None:
    assert set(builtin_scenarios()) == {"full-team", "huskies-bebop-joins", "single-husky"}


@pytest.mark.parametrize("name", ["full-team", "huskies-bebop-joins", "single-husky"])
def test_builtin_scenarios_load(name: str) -> None:
    s = load_scenario(builtin_scenarios()[name])
    assert s.name == name
    assert s.source == str(builtin_scenarios()[name])
    models = s.models()
    assert all(r.model in models for r in s.robots)
    assert s.initially_present()


def test_dynamic_team_scenario_has_the_papers_events() -> None:
    s = load_scenario(builtin_scenarios()["huskies-bebop-joins"])
    assert [r.name for r in s.initially_present()] == ["husky1", "husky2"]
    assert {(e.robot, e.kind) for e in s.events} == {
        ("bebop1", "join"),
        ("husky2", "fail"),
        ("bebop1", "leave"),
    }
    assert all(e.duration > 0 for e in s.events if e.kind == "fail")


def test_full_team_is_the_papers_team() -> None:
    s = load_scenario(builtin_scenarios()["full-team"])
    assert sorted(r.model for r in s.robots) == ["bebop", "husky", "spot"]
    assert s.models() == paper_team()


def test_a_good_file_loads_with_defaults(tmp_path: Path) -> None:
    s = load_scenario(write(tmp_path, GOOD))
    assert (s.name, s.seed, s.objects, s.speedup) == ("test", 3, 4, 500.0)
    assert s.map.cave == CaveSpec(width=30, height=20, seed=2)
    assert s.events == []
    assert s.object_workers == 1
    grid = s.grid()
    assert grid.shape == (20, 30)


def test_json_scenarios_load(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        '{"name": "j", "robots": [{"name": "h", "model": "husky"}], '
        '"map": {"cave": {"width": 20, "height": 15}}}',
        "s.json",
    )
    assert load_scenario(path).name == "j"


def test_a_map_file_is_found_next_to_the_scenario(tmp_path: Path) -> None:
    grid = GridMap.from_array(np.ones((6, 8), dtype=bool), start=(0, 0), decon_area=(5, 7))
    (tmp_path / "maps").mkdir()
    grid.save(tmp_path / "maps" / "room.txt")
    path = write(
        tmp_path,
        "name: m\nrobots: [{name: h, model: husky}]\nmap: {file: maps/room.txt, cell_size_m: 2}\n",
    )
    loaded = load_scenario(path).grid()
    assert loaded.shape == (6, 8)
    assert (loaded.start, loaded.decon_area, loaded.cell_size_m) == ((0, 0), (5, 7), 2.0)


def test_initially_present_excludes_robots_that_join_first() -> None:
    s = Scenario(
        "x",
        [RobotEntry("a", "husky"), RobotEntry("b", "bebop")],
        events=[Event(50, "b", "leave"), Event(10, "b", "join")],
    )
    assert [r.name for r in s.initially_present()] == ["a"]


# -- bad files --------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    rejected(tmp_path / "nope.yaml", "cannot read")


def test_wrong_suffix(tmp_path: Path) -> None:
    rejected(write(tmp_path, GOOD, "scenario.txt"), ".yaml")


def test_invalid_yaml(tmp_path: Path) -> None:
    rejected(write(tmp_path, "name: x\nrobots: [\n"), "not valid YAML")


def test_not_a_mapping(tmp_path: Path) -> None:
    rejected(write(tmp_path, "- 1\n- 2\n"), "object")


@pytest.mark.parametrize(
    ("extra", "fragments"),
    [
        ("speed: 3\n", ("unknown field", "speed")),
        ("sim: {step: 1}\n", ("sim: ", "unknown field", "step")),
        ("agent: {tick: 1}\n", ("agent: ", "unknown field", "tick")),
        ("map: {cave: {width: 30, depth: 3}}\n", ("map.cave: ", "unknown field", "depth")),
    ],
)
def test_unknown_keys(tmp_path: Path, extra: str, fragments: tuple[str, ...]) -> None:
    rejected(write(tmp_path, GOOD.replace("map:", "#map:") + extra), *fragments)


def test_unknown_key_in_a_robot(tmp_path: Path) -> None:
    text = GOOD.replace("{name: husky1, model: husky}", "{name: husky1, model: husky, colour: r}")
    rejected(write(tmp_path, text), "robots[0]: ", "colour")


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("objects: 4", "objects: many", "objects: Expected `int`"),
        ("speedup: 500", "speedup: fast", "speedup: Expected `float`"),
        ("seed: 3", "seed: [3]", "seed: Expected `int`"),
        (
            "{name: bebop1, model: bebop}",
            "{name: bebop1, model: 7}",
            "robots[1].model: Expected `str`",
        ),
        (
            "name: test",
            "name: test\nevents: [{at: soon, robot: husky1, kind: fail}]",
            "events[0].at: Expected `float`",
        ),
        (
            "name: test",
            "name: test\nevents: [{at: 1, robot: husky1, kind: explode}]",
            "events[0].kind: Invalid enum value 'explode'; expected one of 'fail', 'join', 'leave'",
        ),
    ],
)
def test_bad_types(tmp_path: Path, old: str, new: str, field: str) -> None:
    assert old in GOOD
    rejected(write(tmp_path, GOOD.replace(old, new)), field)


def test_missing_required_field(tmp_path: Path) -> None:
    rejected(write(tmp_path, "name: x\n"), "robots")


def test_unknown_robot_model(tmp_path: Path) -> None:
    text = GOOD.replace("model: bebop", "model: drone")
    rejected(write(tmp_path, text), "robots[1].model", "'drone'", "bebop, husky, spot")


def test_duplicate_robot_names(tmp_path: Path) -> None:
    rejected(write(tmp_path, GOOD.replace("name: bebop1", "name: husky1")), "robots", "unique")


@pytest.mark.parametrize("name", ["sim", "operator", "a/b", "''"])
def test_reserved_robot_names(tmp_path: Path, name: str) -> None:
    rejected(write(tmp_path, GOOD.replace("name: bebop1", f"name: {name}")), "robots[1].name")


def test_no_robots(tmp_path: Path) -> None:
    rejected(write(tmp_path, "name: x\nrobots: []\n"), "robots: ", "length >= 1")


def events_file(tmp_path: Path, *events: str) -> Path:
    return write(tmp_path, GOOD + "events:\n" + "".join(f"  - {e}\n" for e in events))


def test_events_naming_unknown_robots(tmp_path: Path) -> None:
    path = events_file(
        tmp_path, "{at: 5, robot: husky1, kind: leave}", "{at: 1, robot: ghost, kind: join}"
    )
    rejected(path, "events[1].robot", "'ghost'")


@pytest.mark.parametrize(
    ("events", "fragments"),
    [
        (
            ["{at: 10, robot: bebop1, kind: leave}", "{at: 20, robot: bebop1, kind: leave}"],
            ("events[1]", "leaves at 20", "not present"),
        ),
        (
            ["{at: 10, robot: bebop1, kind: join}", "{at: 20, robot: bebop1, kind: join}"],
            ("events[1]", "already present"),
        ),
        (["{at: 10, robot: husky1, kind: fail}"], ("events[0].duration", "> 0")),
        (
            [
                "{at: 10, robot: bebop1, kind: leave}",
                "{at: 20, robot: bebop1, kind: fail, duration: 5}",
            ],
            ("events[1]", "fails at 20", "not present"),
        ),
        (["{at: -1, robot: husky1, kind: leave}"], ("events[0]", ">= 0")),
        (["{at: 1, robot: husky1, kind: fail, duration: -3}"], ("events[0]", ">= 0")),
        (
            [
                "{at: 10, robot: husky1, kind: fail, duration: 50}",
                "{at: 30, robot: husky1, kind: leave}",
            ],
            ("events[1]", "failed"),
        ),
        (
            [
                "{at: 10, robot: husky1, kind: fail, duration: 50}",
                "{at: 59, robot: husky1, kind: fail, duration: 5}",
            ],
            ("events[1]", "failed"),
        ),
    ],
)
def test_impossible_events(tmp_path: Path, events: list[str], fragments: tuple[str, ...]) -> None:
    rejected(events_file(tmp_path, *events), *fragments)


def test_possible_events_pass(tmp_path: Path) -> None:
    path = events_file(
        tmp_path,
        "{at: 100, robot: bebop1, kind: join}",  # listed out of order on purpose
        "{at: 10, robot: bebop1, kind: leave}",
        "{at: 20, robot: husky1, kind: fail, duration: 30}",
        "{at: 50, robot: husky1, kind: leave}",  # right when it is back up
        "{at: 200, robot: husky1, kind: join}",
    )
    s = load_scenario(path)
    assert [r.name for r in s.initially_present()] == ["husky1", "bebop1"]


def test_no_robot_present_at_the_start(tmp_path: Path) -> None:
    path = events_file(
        tmp_path, "{at: 5, robot: husky1, kind: join}", "{at: 5, robot: bebop1, kind: join}"
    )
    rejected(path, "events", "no robot is present at the start")


@pytest.mark.parametrize(
    ("map_spec", "fragment"),
    [
        ("{cell_size_m: 1}", "exactly one of"),
        ("{cave: {width: 20}, file: x.txt}", "exactly one of"),
        ("{file: missing.txt}", "no such map file"),
        ("{file: map.bmp}", "unsupported map format"),
        ("{cave: {width: 0, height: 10}}", "map.cave.width: Expected `int` >= 1"),
        ("{cave: {width: 20, height: 10, fill: 1.5}}", "fill"),
        ("{cave: {width: 20, height: 10, iterations: -1}}", "iterations"),
        (
            "{cave: {width: 20, height: 10}, cell_size_m: 0}",
            "map.cell_size_m: Expected `float` > 0",
        ),
    ],
)
def test_bad_map_spec(tmp_path: Path, map_spec: str, fragment: str) -> None:
    text = GOOD.replace("map: {cave: {width: 30, height: 20, seed: 2}}", f"map: {map_spec}")
    rejected(write(tmp_path, text), "map", fragment)


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("speedup: 500", "speedup: 0", "speedup"),
        ("speedup: 500", "speedup: -2", "speedup"),
        ("seed: 3", "seed: 3\ntime_limit_s: 0", "time_limit_s"),
        ("objects: 4", "objects: -1", "objects"),
        ("objects: 4", "objects: 4\ncontaminated_share: 1.5", "objects"),
        ("seed: 3", "seed: 3\nobject_workers: 0", "object_workers"),
        ("seed: 3", "seed: 3\nsim: {failure_chance: 1.0}", "sim.failure_chance"),
        ("seed: 3", "seed: 3\nagent: {heartbeat_s: 5, failure_timeout_s: 5}", "agent"),
        ("seed: 3", "seed: 3\nagent: {keepalive_s: 30, lease_s: 20}", "agent"),
        ("seed: 3", "seed: 3\nagent: {tick_hz: 0}", "agent"),
        ("seed: 3", "seed: 3\nagent: {keepalive_s: 0}", "agent.keepalive_s"),
        ("seed: 3", "seed: 3\nagent: {auction_window_s: -1}", "agent.auction_window_s"),
        ("seed: 3", "seed: 3\nsim: {step_s: 0}", "sim.step_s"),
        ("seed: 3", "seed: 3\nsim: {delay_jitter: 1.5}", "sim.delay_jitter"),
        ("seed: 3", "seed: 3\nallocation: {rebid_on_join: 1.0}", "allocation.rebid_on_join"),
        ("seed: 3", "seed: 3\nallocation: {rebid_on_join: 0}", "allocation.rebid_on_join"),
        ("seed: 3", "seed: 3\nallocation: {queue: true}", "allocation"),
    ],
)
def test_bad_values(tmp_path: Path, old: str, new: str, field: str) -> None:
    rejected(write(tmp_path, GOOD.replace(old, new)), field)


LONG = "r" * 241


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ("seed: 3", "seed: -1", ("seed: Expected `int` >= 0",)),
        ("seed: 2}}", "seed: -2}}", ("map.cave.seed: Expected `int` >= 0",)),
        ("seed: 2}}", "seed: 2, iterations: 101}}", ("map.cave.iterations", "<= 100")),
        ("seed: 3", "seed: 3\nobject_workers: 1001", ("object_workers", "<= 1000")),
        ("name: test", "name: '..'", ("name: '..'", "folder")),
        ("name: test", "name: a/b", ("name: 'a/b'", "folder")),
        ("name: husky1", f"name: {LONG}", ("robots[0].name", "longer than 240 bytes")),
        ("speedup: 500", "speedup: .inf", ("speedup: expected a finite number, got inf",)),
        ("speedup: 500", "speedup: .nan", ("speedup: Expected `float` > 0.0",)),
        ("seed: 3", "seed: 3\ntime_limit_s: .inf", ("time_limit_s: expected a finite number",)),
        ("seed: 2}}", "seed: 2}, cell_size_m: .inf}", ("map.cell_size_m: expected a finite",)),
        ("seed: 3", "seed: 3\ncontaminated_share: .nan", ("contaminated_share: Expected",)),
        (
            "seed: 3",
            "seed: 3\nevents: [{at: .inf, robot: husky1, kind: leave}]",
            ("events[0].at: expected a finite number, got inf",),
        ),
        (
            "seed: 3",
            "seed: 3\nagent: {tick_hz: 0.00001}",
            ("agent.tick_hz: 1e-05", "after its time limit (14400 s)", "at least 6.9"),
        ),
        (
            "seed: 3",
            "seed: 3\nallocation: {strategy: cheapest}",
            (
                "allocation.strategy: allocation strategy 'cheapest'",
                "expected one of auction, seq",
            ),
        ),
        ("seed: 3", "seed: 3\nsource: x.yaml", ("source: not a field of a scenario file",)),
    ],
)
def test_values_that_would_crash_or_hang_a_run(
    tmp_path: Path, old: str, new: str, fragments: tuple[str, ...]
) -> None:
    assert old in GOOD
    rejected(write(tmp_path, GOOD.replace(old, new)), *fragments)


@pytest.mark.parametrize(
    ("cave", "fragments"),
    [
        ("{width: 100000, height: 100000}", ("map.cave: 100000x100000 = 10000000000 cells",)),
        ("{width: 40000, height: 40000}", ("map.cave: a 40000x40000 map needs up to 2.", "TiB")),
    ],
)
def test_a_cave_too_big_for_memory_is_refused_before_it_is_generated(
    tmp_path: Path, cave: str, fragments: tuple[str, ...]
) -> None:
    text = GOOD.replace("{cave: {width: 30, height: 20, seed: 2}}", f"{{cave: {cave}}}")
    rejected(write(tmp_path, text), *fragments, "more than" if "TiB" in fragments else "at most")


def test_a_map_file_too_big_for_memory_is_refused_once_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    GridMap.from_array(np.ones((6, 8), dtype=bool)).save(tmp_path / "room.txt")
    text = GOOD.replace("{cave: {width: 30, height: 20, seed: 2}}", "{file: room.txt}")
    monkeypatch.setattr("btcap.sim.mission.footprint.memory_limit", lambda: 10_000)
    rejected(write(tmp_path, text), "map.file: a 8x6 map needs up to", "of memory here")


def test_more_objects_than_cells_are_refused_before_the_cave_is_generated(tmp_path: Path) -> None:
    text = GOOD.replace("objects: 4", "objects: 100000")
    rejected(write(tmp_path, text), "objects: 100000 objects on a 30x20 map", "at most one")


def test_more_objects_than_reachable_cells_are_refused(tmp_path: Path) -> None:
    reachable = int(GridMap.generate_cave(30, 20, seed=2).reachable.sum())
    assert reachable < 30 * 20
    load_scenario(write(tmp_path, GOOD.replace("objects: 4", f"objects: {reachable}")))
    text = GOOD.replace("objects: 4", f"objects: {reachable + 1}")
    rejected(
        write(tmp_path, text), f"objects: {reachable + 1} objects; expected at most {reachable}"
    )


def test_check_scenario_applies_the_bounds_of_the_file_to_python_built_scenarios() -> None:
    cave = MapSpec(cave=CaveSpec(20, 15))
    bad = Scenario("py", [RobotEntry("h", "husky")], map=cave, objects=-1, source="built.py")
    with pytest.raises(ScenarioError, match=re.escape("built.py: objects: Expected `int` >= 0")):
        check_scenario(bad)
    inf = Scenario("py", [RobotEntry("h", "husky")], map=cave, speedup=float("inf"))
    with pytest.raises(ScenarioError, match="speedup: expected a finite number"):
        check_scenario(inf)


def test_check_scenario_validates_python_built_scenarios() -> None:
    s = Scenario("py", [RobotEntry("h", "husky")], map=MapSpec(cave=CaveSpec(20, 15)))
    assert check_scenario(s) is s
    bad = Scenario("py", [RobotEntry("h", "tank")], source="made-in-python")
    with pytest.raises(ScenarioError, match=re.escape("made-in-python: robots[0].model")):
        check_scenario(bad)


# -- team files -------------------------------------------------------------------------------

TEAM = """\
models:
  rover:
    cost_factor: 1.5
    speed_mps: 2
    explore: {duration_s: 20, radius_m: 10}
    identify: {duration_s: 5}
  crane:
    cost_factor: 3
    decontaminate: {duration_s: 4}
"""


def test_a_team_file_loads(tmp_path: Path) -> None:
    models = load_team(write(tmp_path, TEAM, "team.yaml"))
    assert set(models) == {"rover", "crane"}
    rover = models["rover"]
    assert rover.can("explore")
    assert rover.can("identify")
    assert not rover.can("decontaminate")
    assert rover.operation("explore").radius_m == 10
    with pytest.raises(ValueError, match="cannot decontaminate"):
        rover.operation("decontaminate")


def test_a_scenario_uses_its_team_file(tmp_path: Path) -> None:
    (tmp_path / "teams").mkdir()
    write(tmp_path / "teams", TEAM, "mine.yaml")
    text = GOOD.replace("model: husky", "model: rover").replace("model: bebop", "model: crane")
    s = load_scenario(write(tmp_path, text + "team_file: teams/mine.yaml\n"))
    assert set(s.models()) == {"rover", "crane"}


def test_a_scenario_with_a_bad_team_file_names_both_files(tmp_path: Path) -> None:
    team = write(tmp_path, TEAM.replace("cost_factor: 3", "cost_factor: 0"), "team.yaml")
    err = rejected(write(tmp_path, GOOD + "team_file: team.yaml\n"), "team_file")
    assert str(team) in str(err)
    rejected(write(tmp_path, GOOD + "team_file: nowhere.yaml\n"), "team_file", "cannot read")


@pytest.mark.parametrize(
    ("old", "new", "fragment"),
    [
        ("cost_factor: 3", "cost_factor: 0", "models.crane"),
        ("speed_mps: 2", "speed_mps: -1", "models.rover"),
        ("{duration_s: 5}", "{duration_s: -5}", "models.rover.identify"),
        ("radius_m: 10", "radius_m: 0", "models.rover.explore.radius_m"),
        ("{duration_s: 4}", "{duration_s: 4, power: 9}", "power"),
        ("cost_factor: 3", "cost_factor: heavy", "cost_factor"),
        ("models:", "robots:", "models"),
        ("cost_factor: 3", "cost_factor: .inf", "models.crane.cost_factor: expected a finite"),
        ("{duration_s: 4}", "{duration_s: .nan}", "models.crane.decontaminate.duration_s"),
    ],
)
def test_bad_team_files(tmp_path: Path, old: str, new: str, fragment: str) -> None:
    assert old in TEAM
    path = write(tmp_path, TEAM.replace(old, new), "team.yaml")
    with pytest.raises(TeamFileError) as info:
        load_team(path)
    assert str(path) in str(info.value)
    assert fragment in str(info.value)


def test_team_file_missing_or_invalid(tmp_path: Path) -> None:
    with pytest.raises(TeamFileError, match="cannot read"):
        load_team(tmp_path / "none.yaml")
    path = write(tmp_path, "models: [\n", "team.yaml")
    with pytest.raises(TeamFileError, match="not valid"):
        load_team(path)
    json_team = write(tmp_path, '{"models": {"m": {"cost_factor": 1}}}', "team.json")
    assert load_team(json_team)["m"].cost_factor == 1
