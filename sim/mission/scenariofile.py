"""The schema of a scenario file (``btcap run``, ``btcap sweep``): its msgspec types, each
field with its meaning and bounds, so msgspec refuses a bad value naming the field and
the file reference (``btcap schema scenario``, docs/files.md) is generated from them.

:mod:`btcap.sim.mission.scenario` reads the file and checks what the types cannot say.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import msgspec

from btcap.sim.world.grid import GridMap
from btcap.sim.world.model import RobotModel, load_team, paper_team
from btcap.team.rossettings import (
    DomainId,
    Qos,
    RosBackend,
    RosSettings,
    check_master_uri,
    check_namespace,
    check_node_name,
)
from btcap.team.settings import (
    Allocation,
    AuctionWindowS,
    AwardTimeoutS,
    FailureTimeoutS,
    HeartbeatS,
    KeepaliveS,
    LeaseS,
    TickHz,
    Timing,
)

__all__ = [
    "NO_SOURCE",
    "AgentTiming",
    "Allocation",
    "CaveSpec",
    "Event",
    "MapSpec",
    "RobotEntry",
    "Scenario",
    "ScenarioRos",
    "SimSettings",
]

#: The ``source`` of a scenario not read from a file.
NO_SOURCE = "<scenario>"


def _doc(text: str) -> msgspec.Meta:
    return msgspec.Meta(description=text)


def _seconds(text: str) -> msgspec.Meta:
    return msgspec.Meta(gt=0, description=f"{text} (mission seconds).")


class CaveSpec(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A cellular-automaton cave generated from a seed, reduced to its largest connected
    part; the robots start on its left, the decontamination area is the free cell
    farthest from the start."""

    width: Annotated[int, msgspec.Meta(ge=1, description="Cells across (columns).")] = 120
    height: Annotated[int, msgspec.Meta(ge=1, description="Cells down (rows).")] = 80
    seed: Annotated[
        int, msgspec.Meta(ge=0, description="The cave's seed: the same seed, the same cave.")
    ] = 7
    fill: Annotated[
        float,
        msgspec.Meta(
            ge=0,
            lt=1,
            description="Share of cells that start as wall before smoothing: more, narrower caves.",
        ),
    ] = 0.45
    iterations: Annotated[
        int,
        msgspec.Meta(
            ge=0,
            le=100,
            description="Smoothing rounds: a cell becomes wall when 5 of its 3x3 block are.",
        ),
    ] = 5


class MapSpec(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """The cave: exactly one of a generated ``cave`` or a map ``file``."""

    cave: Annotated[CaveSpec | None, _doc("A generated cave.")] = None
    file: Annotated[
        str | None,
        _doc(
            "A map file, relative to the scenario file: `.npy` (bool or 0/1, 1 = free), "
            "`.png` (dark = wall) or `.txt` (`#` wall, `.` free, `S` start, `D` "
            "decontamination area)."
        ),
    ] = None
    cell_size_m: Annotated[
        float, msgspec.Meta(gt=0, description="The side of a cell in metres.")
    ] = 1.0


class RobotEntry(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A robot of the team."""

    name: Annotated[
        str,
        _doc(
            "Its name: unique, non-empty, without `/`, at most 240 bytes, not `sim`, "
            "`operator` or `*`."
        ),
    ]
    model: Annotated[
        str,
        _doc(
            "Its robot model: `husky`, `spot` or `bebop` (the paper's team), or a model "
            "of the `team_file`."
        ),
    ]


class Event(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """``join`` at ``at``; ``leave`` at ``at``; ``fail`` at ``at`` for ``duration`` seconds."""

    at: Annotated[float, msgspec.Meta(ge=0, description="When (mission seconds).")]
    robot: Annotated[str, _doc("Which robot: a name of `robots`.")]
    kind: Annotated[
        Literal["join", "leave", "fail"],
        _doc(
            "`join` (a robot whose first event is a join is away at the start), `leave` "
            "(says goodbye) or `fail` (falls silent for `duration`, then comes back)."
        ),
    ]
    duration: Annotated[
        float, msgspec.Meta(ge=0, description="How long a `fail` lasts (> 0 for a fail).")
    ] = 0.0


class SimSettings(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """The pace and randomness of the simulation manager."""

    step_s: Annotated[float, _seconds("Robots move and operations are checked once a step")] = 0.5
    delay_jitter: Annotated[
        float,
        msgspec.Meta(
            ge=0,
            le=1,
            description="An operation takes its model's duration times a random factor "
            "within [1 - jitter, 1 + jitter].",
        ),
    ] = 0.2
    failure_chance: Annotated[
        float,
        msgspec.Meta(ge=0, lt=1, description="The chance that an operation fails."),
    ] = 0.05


#: What ``ros.namespace`` replaces by each robot's name.
ROBOT_FIELD = "{robot}"


class ScenarioRos(msgspec.Struct, forbid_unknown_fields=True, kw_only=True, frozen=True):
    """The simulated robots behind ROS 2 (or ROS 1: ``backend``): the graph they join,
    each robot's namespace and node, the QoS of their topics. The file having this block
    puts them there, as ``--ros2`` (``--ros1``) does with these defaults; each robot's
    node gets the agent file's ``ros`` settings
    (:class:`~btcap.team.rossettings.RosSettings`) made from it."""

    backend: Annotated[
        RosBackend,
        _doc(
            "`ros2` (docs/ros2-sim.md), or `ros1`: each robot a `move_base` action server "
            "and the manager's operations ROS 1 services, as in the paper (docs/ros1.md), "
            "as `--ros1` does."
        ),
    ] = "ros2"
    master_uri: Annotated[
        str | None,
        _doc("ROS 1 only: the master to serve on; null: the run starts its own on loopback."),
    ] = None
    domain_id: DomainId = None
    namespace: Annotated[
        str,
        _doc(
            "Each robot's namespace, `{robot}` standing for its name: its navigation action "
            "(`navigate_to_pose`), operations (`explore`, `identify`, `decontaminate`), "
            "`pose` and `state` topics and `stop` service are served there."
        ),
    ] = "/" + ROBOT_FIELD
    node_name: Annotated[str, _doc("The name of each robot's ROS node (in its namespace).")] = (
        "btcap"
    )
    qos: Annotated[Qos, _doc("QoS of the robots' topics (the `pose` topic, subscriptions).")] = (
        msgspec.field(default_factory=Qos)
    )

    def __post_init__(self) -> None:
        if ROBOT_FIELD not in self.namespace:
            raise ValueError(
                f"namespace: {self.namespace!r} has no {ROBOT_FIELD}: expected a pattern "
                "giving each robot a namespace of its own ('/{robot}', '/team/{robot}')"
            )
        check_namespace(self.namespace.replace(ROBOT_FIELD, "robot"), backend=self.backend)
        check_node_name(self.node_name, backend=self.backend)
        check_master_uri(self.master_uri)

    def namespace_of(self, robot: str) -> str:
        """``robot``'s namespace (ValueError if its name makes no ROS name)."""
        ns = self.namespace.replace(ROBOT_FIELD, robot)
        return check_namespace(ns, f"ros.namespace (for robot {robot!r})", self.backend)

    def settings(self, robot: str) -> RosSettings:
        """The ``ros`` settings of ``robot``'s node, as its agent file would have them."""
        return RosSettings(
            backend=self.backend,
            master_uri=self.master_uri,
            domain_id=self.domain_id,
            namespace=self.namespace_of(robot),
            node_name=self.node_name,
            qos=self.qos,
        )


class AgentTiming(Timing, frozen=True):
    """Every robot's protocol timing (:class:`~btcap.team.settings.Timing`), in simulated
    seconds (the clock runs on mission time, scaled by the speed-up like everything else).
    The defaults suit a mission of hours, not a robot's real-time library defaults."""

    tick_hz: TickHz = 2.0
    heartbeat_s: HeartbeatS = 2.0
    failure_timeout_s: FailureTimeoutS = 15.0
    lease_s: LeaseS = 20.0
    keepalive_s: KeepaliveS = 2.0
    auction_window_s: AuctionWindowS = 5.0
    award_timeout_s: AwardTimeoutS = 10.0


class Scenario(msgspec.Struct, forbid_unknown_fields=True):
    """One mission: who takes part, what happens to them, and how fast time runs."""

    name: Annotated[
        str,
        msgspec.Meta(
            min_length=1,
            description="The scenario's name, shown in the summary; with `--compare`, the "
            "name of its output folder (so no `/`, and not `.` or `..`).",
        ),
    ]
    robots: Annotated[
        list[RobotEntry],
        msgspec.Meta(
            min_length=1,
            description="The team: present from the start unless a robot's first event is "
            "a `join`.",
        ),
    ]
    description: Annotated[str, _doc("A line for people; not used.")] = ""
    map: Annotated[MapSpec, _doc("The cave: generated or read from a file.")] = MapSpec(
        cave=CaveSpec()
    )
    seed: Annotated[
        int,
        msgspec.Meta(
            ge=0,
            description="The mission's seed: where the objects lie, which are contaminated, "
            "and the simulation's delays and failures.",
        ),
    ] = 1
    objects: Annotated[
        int,
        msgspec.Meta(
            ge=0,
            description="Objects scattered over the cells reachable from the start, at most "
            "one per cell.",
        ),
    ] = 10
    contaminated_share: Annotated[
        float,
        msgspec.Meta(ge=0, le=1, description="The chance that an object is contaminated."),
    ] = 0.5
    speedup: Annotated[
        float,
        msgspec.Meta(
            gt=0,
            description="Mission seconds per wall second on the wall clock (`btcap run` "
            "without `--fast`, which runs as fast as it can).",
        ),
    ] = 100.0
    time_limit_s: Annotated[float, _seconds("The mission stops unfinished after this long")] = (
        4 * 3600.0
    )
    object_workers: Annotated[
        int,
        msgspec.Meta(
            ge=1,
            le=1000,
            description="Identify-and-decontaminate loops of the mission tree, run in parallel.",
        ),
    ] = 1
    mission: Annotated[
        Literal["paper", "pool"],
        _doc(
            "The mission tree: `paper`, the paper's (one Explore loop beside "
            "`object_workers` identify-and-decontaminate loops), or `pool` (a lane per "
            "goal and per object found, which identifies the object and carries it if "
            "contaminated, the carry auctioned the moment it is identified; as many "
            "explorations and identifications at once as robots can do them)."
        ),
    ] = "paper"
    bids: Annotated[
        Literal["paper", "time"],
        _doc(
            "What robots bid for work: `paper`, the paper's cost units (metres driven x "
            "the model's `cost_factor`, plus seconds of work), or `time`, seconds (the "
            "drive at the model's `speed_mps`, plus the work), so work goes to the robot "
            "that ends it first (docs/mission.md, Fig. 5)."
        ),
    ] = "paper"
    team_file: Annotated[
        str | None,
        _doc(
            "A team file of robot models, relative to the scenario file; null: the paper's "
            "team (`husky`, `spot`, `bebop`)."
        ),
    ] = None
    events: Annotated[list[Event], _doc("Joins, leaves and failures, in any order.")] = []
    sim: Annotated[SimSettings, _doc("The simulation's pace and randomness.")] = SimSettings()
    agent: Annotated[AgentTiming, _doc("Every robot's protocol timing.")] = AgentTiming()
    allocation: Annotated[Allocation, _doc("How work is allocated and moved.")] = Allocation()
    ros: Annotated[
        ScenarioRos | None,
        _doc(
            "The robots behind ROS 2 (docs/ros2-sim.md): `btcap run` and `btcap sim serve` "
            "serve each through ROS 2 interfaces in its namespace, as `--ros2` does; needs "
            "ROS 2 and the simulator's interfaces (`make ros-sim`); the fast mode (`btcap "
            "sweep`) leaves it aside. null: robots reached directly, unless `--ros2`."
        ),
    ] = None
    source: Annotated[
        str,
        msgspec.Meta(
            description="The file the scenario was read from (set by the loader).",
            extra={"internal": True},
        ),
    ] = NO_SOURCE

    def models(self) -> dict[str, RobotModel]:
        if self.team_file is None:
            return paper_team()
        path = Path(self.team_file)
        if not path.is_absolute() and self.source not in (NO_SOURCE, ""):
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
