"""Scenario files: map, seed, team, events and timing of one simulated mission."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import msgspec

from btcap.sim.catalog import builtin_scenarios
from btcap.sim.grid import GridMap, MapError
from btcap.sim.model import RobotModel, load_team, paper_team
from btcap.team.core.planning import STRATEGIES

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
    "load_scenario",
]


class ScenarioError(ValueError):
    """A scenario file is invalid; the message names the file and the field."""


class CaveSpec(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    width: int = 120
    height: int = 80
    seed: int = 7
    fill: float = 0.45
    iterations: int = 5


class MapSpec(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """Either a generated cave or a map file (relative to the scenario file)."""

    cave: CaveSpec | None = None
    file: str | None = None
    cell_size_m: float = 1.0


class RobotEntry(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    name: str
    model: str


class Event(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """``join`` at ``at``; ``leave`` at ``at``; ``fail`` at ``at`` for ``duration`` seconds."""

    at: float
    robot: str
    kind: Literal["join", "leave", "fail"]
    duration: float = 0.0


class SimSettings(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    step_s: float = 0.5
    delay_jitter: float = 0.2
    failure_chance: float = 0.05


class AgentTiming(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """Protocol timing in simulated seconds (scaled by the speed-up like everything else)."""

    tick_hz: float = 2.0
    heartbeat_s: float = 2.0
    failure_timeout_s: float = 15.0
    lease_s: float = 20.0
    keepalive_s: float = 2.0
    auction_window_s: float = 5.0
    award_timeout_s: float = 10.0


class Allocation(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """Optional policies of the auctions (see :class:`btcap.team.mission.MissionConfig`)."""

    #: Re-evaluate running work this often (clock seconds) and when the team changes;
    #: None: running work never moves.
    reevaluate_s: float | None = 30.0
    #: Work moves only to a robot bidding at least this fraction below what the current
    #: executor now bids to finish it.
    move_margin: float = 0.2
    #: ``auction``, ``sequential``, ``optimal`` or ``arrival`` (btcap.team.core.planning).
    strategy: str = "auction"
    #: Older name of ``move_margin`` for joins (None: ``move_margin`` applies).
    rebid_on_join: float | None = None
    #: A busy robot bids for one more task, to start after its current one.
    queue_after_current: bool = False


class Scenario(msgspec.Struct, forbid_unknown_fields=True):
    """One mission: who takes part, what happens to them, and how fast time runs."""

    name: str
    robots: list[RobotEntry]
    description: str = ""
    map: MapSpec = MapSpec(cave=CaveSpec())
    seed: int = 1
    objects: int = 10
    contaminated_share: float = 0.5
    speedup: float = 100.0
    time_limit_s: float = 4 * 3600.0
    object_workers: int = 1
    team_file: str | None = None
    events: list[Event] = []
    sim: SimSettings = SimSettings()
    agent: AgentTiming = AgentTiming()
    allocation: Allocation = Allocation()
    source: str = "<scenario>"

    def models(self) -> dict[str, RobotModel]:
        if self.team_file is None:
            return paper_team()
        path = Path(self.team_file)
        if not path.is_absolute() and self.source not in ("<scenario>", ""):
            path = Path(self.source).parent / path
        return load_team(path)

    def grid(self) -> GridMap:
        spec = self.map
        if spec.file is not None:
            path = Path(spec.file)
            if not path.is_absolute():
                path = Path(self.source).parent / path
            return GridMap.load(path, cell_size_m=spec.cell_size_m)
        cave = spec.cave or CaveSpec()
        return GridMap.generate_cave(
            cave.width,
            cave.height,
            seed=cave.seed,
            fill=cave.fill,
            iterations=cave.iterations,
            cell_size_m=spec.cell_size_m,
        )

    def initially_present(self) -> list[RobotEntry]:
        """Robots present from the start: all but those whose first event is a join."""
        first: dict[str, str] = {}
        for e in sorted(self.events, key=lambda e: e.at):
            first.setdefault(e.robot, e.kind)
        return [r for r in self.robots if first.get(r.name) != "join"]


def _check(s: Scenario, where: str) -> Scenario:
    def bad(field: str, expected: str) -> ScenarioError:
        return ScenarioError(f"{where}: {field}: {expected}")

    if not s.robots:
        raise bad("robots", "expected at least one robot")
    names = [r.name for r in s.robots]
    if len(set(names)) != len(names):
        raise bad("robots", f"robot names must be unique, got {names}")
    for i, r in enumerate(s.robots):
        if not r.name or "/" in r.name or r.name in ("sim", "operator", "*"):
            raise bad(f"robots[{i}].name", f"{r.name!r} is reserved or contains '/'")
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
    for field, value in (("speedup", s.speedup), ("time_limit_s", s.time_limit_s)):
        if not value > 0:
            raise bad(field, f"expected > 0, got {value}")
    if s.objects < 0 or not 0 <= s.contaminated_share <= 1:
        raise bad("objects", "expected objects >= 0 and 0 <= contaminated_share <= 1")
    if s.object_workers < 1:
        raise bad("object_workers", "expected >= 1")
    if not 0 <= s.sim.failure_chance < 1:
        raise bad("sim.failure_chance", f"expected within [0, 1), got {s.sim.failure_chance}")
    if not s.sim.step_s > 0:
        raise bad("sim.step_s", f"expected > 0, got {s.sim.step_s}")
    if not 0 <= s.sim.delay_jitter <= 1:
        raise bad("sim.delay_jitter", f"expected within [0, 1], got {s.sim.delay_jitter}")
    if s.allocation.strategy not in STRATEGIES:
        got = s.allocation.strategy
        raise bad("allocation.strategy", f"expected one of {', '.join(STRATEGIES)}, got {got!r}")
    every = s.allocation.reevaluate_s
    if every is not None and not (math.isfinite(every) and every > 0):
        raise bad("allocation.reevaluate_s", f"expected seconds > 0 or null, got {every}")
    if not 0 <= s.allocation.move_margin < 1:
        raise bad(
            "allocation.move_margin", f"expected within [0, 1), got {s.allocation.move_margin}"
        )
    margin = s.allocation.rebid_on_join
    if margin is not None and not 0 < margin < 1:
        raise bad("allocation.rebid_on_join", f"expected a fraction within (0, 1), got {margin}")
    t = s.agent
    for name in AgentTiming.__struct_fields__:
        if not getattr(t, name) > 0:
            raise bad(f"agent.{name}", f"expected > 0, got {getattr(t, name)}")
    if t.failure_timeout_s <= t.heartbeat_s or t.lease_s <= t.keepalive_s or t.tick_hz <= 0:
        raise bad(
            "agent", "expected failure_timeout_s > heartbeat_s, lease_s > keepalive_s, tick_hz > 0"
        )
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
    try:
        s.grid()
    except (MapError, ValueError, OSError) as exc:  # generate_cave raises ValueError
        raise bad("map", str(exc)) from None
    return s


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
        raise ScenarioError(f"{file}: {exc}") from None
    except msgspec.DecodeError as exc:
        raise ScenarioError(f"{file}: not valid YAML/JSON ({exc})") from None
    s.source = str(file)
    return _check(s, str(file))


def check_scenario(s: Scenario) -> Scenario:
    """Validate a scenario built in Python."""
    return _check(s, s.source)
