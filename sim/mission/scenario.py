"""Scenario files: map, seed, team, events and timing of one simulated mission.

The file's types, with every field's meaning and bounds, are in
:mod:`btcap.sim.mission.scenariofile` (re-exported here; the ``agent`` and ``allocation`` blocks
are the settings of :mod:`btcap.team.settings`). This module reads a file and refuses an
impossible scenario before anything big is allocated (a map this machine cannot hold,
more objects than free cells), in one line naming the file and the field.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import msgspec

from btcap.errors import BtcapError
from btcap.sim.mission.catalog import builtin_scenarios
from btcap.sim.mission.footprint import map_too_big
from btcap.sim.mission.scenariofile import (
    NO_SOURCE,
    AgentTiming,
    Allocation,
    CaveSpec,
    Event,
    MapSpec,
    RobotEntry,
    Scenario,
    ScenarioRos,
    SimSettings,
)
from btcap.sim.world.grid import MapError
from btcap.team.filecheck import field_first, not_finite
from btcap.team.rossettings import ros_label
from btcap.transports.zmq_endpoints import check_id

__all__ = [
    "AgentTiming",
    "Allocation",
    "CaveSpec",
    "Event",
    "MapSpec",
    "RobotEntry",
    "Scenario",
    "ScenarioError",
    "SimSettings",
    "builtin_scenarios",
    "check_ros_names",
    "check_scenario",
    "grow_team",
    "load_scenario",
    "resolve_scenario",
    "run_metadata",
]

_RESERVED = ("sim", "operator")
_NOT_IN_FOLDER_NAMES = ("/", "\\", "\0")


class ScenarioError(BtcapError, ValueError):
    """A scenario file is invalid; the message names the file and the field."""


#: Makes the error for a field and what was expected of it.
_Bad = Callable[[str, str], ScenarioError]


def _check(s: Scenario, where: str) -> Scenario:
    def bad(field: str, expected: str) -> ScenarioError:
        return ScenarioError(f"{where}: {field}: {expected}")

    if (why := not_finite(s)) is not None:
        raise bad(*why)
    if s.name in ("", ".", "..") or any(c in s.name for c in _NOT_IN_FOLDER_NAMES):
        raise bad("name", f"{s.name!r}: expected a name that can name a folder (no '/')")
    if not s.robots:
        raise bad("robots", "expected at least one robot")
    names = [r.name for r in s.robots]
    if len(set(names)) != len(names):
        raise bad("robots", f"robot names must be unique, got {names}")
    for i, r in enumerate(s.robots):
        why_id = check_id(r.name)
        if why_id is not None or r.name in _RESERVED:
            expected = why_id or f"{', '.join(_RESERVED)} are reserved"
            raise bad(f"robots[{i}].name", f"{r.name!r}: {expected}")
    try:
        models = s.models()
    except ValueError as exc:
        raise bad("team_file", str(exc)) from None
    for i, r in enumerate(s.robots):
        if r.model not in models:
            raise bad(
                f"robots[{i}].model", f"{r.model!r}; expected one of {', '.join(sorted(models))}"
            )
    if (s.map.cave is None) == (s.map.file is None):
        raise bad("map", "expected exactly one of 'cave' or 'file'")
    from btcap.team.allocation.strategies import (
        check_strategy,  # loads plug-ins' names only if needed
    )

    try:
        check_strategy(s.allocation.strategy)
    except ValueError as exc:
        raise bad("allocation.strategy", str(exc)) from None
    t = s.agent
    if 1 / t.tick_hz > s.time_limit_s:  # the time limit is checked when the mission ticks
        raise bad(
            "agent.tick_hz",
            f"{t.tick_hz:g}: the mission would first tick after its time limit "
            f"({s.time_limit_s:g} s); expected at least {1 / s.time_limit_s:g}",
        )
    _check_events(s, bad)
    _check_map(s, bad)
    if s.ros is not None:
        check_ros_names(s, s.ros)
    return s


def check_ros_names(s: Scenario, ros: ScenarioRos) -> None:
    """ScenarioError, naming the file and robot, if a robot's name makes no namespace of
    the ROS of ``ros`` (the scenario's block, or the defaults ``--ros2``/``--ros1`` use)."""
    label = ros_label(ros.backend)
    for i, r in enumerate(s.robots):
        try:
            ros.namespace_of(r.name)
        except ValueError as exc:
            raise ScenarioError(
                f"{s.source}: robots[{i}].name: {r.name!r} makes no {label} namespace "
                f"({exc}); expected letters, digits and '_' behind {label}"
            ) from None


def _check_events(s: Scenario, bad: _Bad) -> None:
    present = {r.name: True for r in s.initially_present()}
    for r in s.robots:
        present.setdefault(r.name, False)
    if not any(present.values()):
        raise bad("events", "no robot is present at the start")
    down_until: dict[str, float] = {}
    for k in sorted(range(len(s.events)), key=lambda k: s.events[k].at):
        e = s.events[k]
        where_e = f"events[{k}]"
        if e.robot not in present:
            raise bad(f"{where_e}.robot", f"{e.robot!r} is not in robots")
        if e.at < 0 or e.duration < 0:
            raise bad(where_e, "at and duration must be >= 0")
        if e.at < down_until.get(e.robot, 0.0):
            raise bad(
                where_e,
                f"{e.robot} {e.kind}s at {e.at} while it is failed (until {down_until[e.robot]})",
            )
        if e.kind == "join":
            if present[e.robot]:
                raise bad(where_e, f"{e.robot} joins at {e.at} but is already present")
            present[e.robot] = True
        elif e.kind == "leave":
            if not present[e.robot]:
                raise bad(where_e, f"{e.robot} leaves at {e.at} but is not present")
            present[e.robot] = False
        elif e.kind == "fail":
            if not present[e.robot]:
                raise bad(where_e, f"{e.robot} fails at {e.at} but is not present")
            if e.duration <= 0:
                raise bad(f"{where_e}.duration", "a failure needs a duration > 0")
            down_until[e.robot] = e.at + e.duration


def _check_map(s: Scenario, bad: _Bad) -> None:
    """The map fits in memory and holds the objects: a generated cave is sized before it
    is generated, a map file once read; objects go on cells reachable from the start."""
    robots = len(s.robots)
    cave = s.map.cave
    if cave is not None:
        if (why := map_too_big(cave.height, cave.width, robots)) is not None:
            raise bad("map.cave", why)
        if s.objects > cave.width * cave.height:
            raise bad(
                "objects",
                f"{s.objects} objects on a {cave.width}x{cave.height} map; expected at most "
                "one per reachable cell",
            )
    try:
        grid = s.grid()
    except (MapError, ValueError, OSError) as exc:  # generate_cave raises ValueError
        raise bad("map", str(exc)) from None
    if cave is None and (why := map_too_big(grid.height, grid.width, robots)) is not None:
        raise bad("map.file", why)
    reachable = int(grid.reachable.sum())
    if s.objects > reachable:
        raise bad(
            "objects",
            f"{s.objects} objects; expected at most {reachable}, one per cell reachable from "
            "the start of this map",
        )


def load_scenario(path: str | Path) -> Scenario:
    """Read and check a scenario (YAML or JSON); errors name the file and the field."""
    file = Path(path)
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{file}: cannot read ({exc.strerror})") from None
    try:
        if file.suffix in (".yaml", ".yml"):
            s = msgspec.yaml.decode(data, type=Scenario)
        elif file.suffix == ".json":
            s = msgspec.json.decode(data, type=Scenario)
        else:
            raise ScenarioError(f"{file}: expected a .yaml, .yml or .json file")
    except msgspec.ValidationError as exc:
        raise ScenarioError(f"{file}: {field_first(str(exc), Scenario)}") from None
    except msgspec.DecodeError as exc:
        raise ScenarioError(f"{file}: not valid YAML/JSON ({exc})") from None
    if s.source != NO_SOURCE:
        raise ScenarioError(f"{file}: source: not a field of a scenario file (the loader sets it)")
    s.source = str(file)
    return _check(s, str(file))


def check_scenario(s: Scenario) -> Scenario:
    """Validate a scenario built in Python: the bounds its types give (as when read from a
    file), then everything :func:`load_scenario` checks."""
    try:
        msgspec.convert(msgspec.to_builtins(s), Scenario)
    except msgspec.ValidationError as exc:
        raise ScenarioError(f"{s.source}: {field_first(str(exc), Scenario)}") from None
    return _check(s, s.source)


def grow_team(s: Scenario, robots: int) -> None:
    """Add robots to ``s`` until it has ``robots``: its robots' models in turn, each
    named after its model and the next free number (husky2, spot2, bebop2, husky3, ...);
    ValueError if it already has more."""
    if robots < len(s.robots):
        raise ValueError(f"expected at least the scenario's {len(s.robots)} robots, got {robots}")
    names = {r.name for r in s.robots}
    models = [r.model for r in s.robots]
    count: dict[str, int] = {}
    for i in range(robots - len(s.robots)):
        model = models[i % len(models)]
        n = count.get(model, 1)
        while f"{model}{n}" in names:
            n += 1
        count[model] = n
        names.add(f"{model}{n}")
        s.robots.append(RobotEntry(f"{model}{n}", model))


def run_metadata(s: Scenario, *, fast: bool, distributed: bool) -> dict[str, str]:
    """What a recording says about its run (MCAP metadata, the JSON Lines header):
    scenario, seed, strategy, how it ran and every setting, as JSON."""
    mode = "fast" if fast else "distributed" if distributed else "speed-up"
    return {
        "scenario": s.name,
        "seed": str(s.seed),
        "strategy": s.allocation.strategy,
        "mode": mode,
        "settings": msgspec.json.encode(s).decode(),
    }


def resolve_scenario(ref: str) -> Scenario:
    """A built-in scenario name or a path to a scenario file."""
    builtins = builtin_scenarios()
    if ref in builtins:
        return load_scenario(builtins[ref])
    path = Path(ref)
    if not path.exists():
        raise ScenarioError(
            f"scenario {ref!r}: no such file, and not a built-in ({', '.join(builtins)})"
        )
    return load_scenario(path)
