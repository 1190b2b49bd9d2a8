"""Robot models (what each kind of robot can do, how fast, at what cost) and team files."""

from __future__ import annotations

from pathlib import Path

import msgspec

__all__ = ["OperationModel", "RobotModel", "TeamFile", "TeamFileError", "load_team", "paper_team"]


class TeamFileError(ValueError):
    """A team file is invalid; the message names the file and the field."""


class OperationModel(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """One sim operation a robot can perform: mean duration and, for explore, a radius."""

    duration_s: float
    radius_m: float = 0.0


class RobotModel(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A kind of robot; the paper's table gives durations, radii and cost factors."""

    cost_factor: float
    speed_mps: float = 1.0
    explore: OperationModel | None = None
    identify: OperationModel | None = None
    decontaminate: OperationModel | None = None

    def can(self, op: str) -> bool:
        return getattr(self, op) is not None

    def operation(self, op: str) -> OperationModel:
        model: OperationModel | None = getattr(self, op, None)
        if model is None:
            raise ValueError(f"this robot model cannot {op}")
        return model


class TeamFile(msgspec.Struct, forbid_unknown_fields=True):
    """``models``: robot kinds by name."""

    models: dict[str, RobotModel]


def paper_team() -> dict[str, RobotModel]:
    """The team of the paper (section IV): Husky, Spot and Bebop.

    Cost factors, durations and radii are the paper's table; the speeds are invented
    here (the paper gives none): they set how long a drive takes, not what it costs.
    """
    return {
        "husky": RobotModel(
            cost_factor=2.0,  # paper
            speed_mps=1.0,  # invented
            explore=OperationModel(60.0, 15.0),  # paper: 60 s, 15 m radius
            identify=OperationModel(60.0),  # paper
            decontaminate=OperationModel(8.0),  # paper
        ),
        # paper: cost factor 1.25, Identify 2 s; speed invented
        "spot": RobotModel(cost_factor=1.25, speed_mps=1.5, identify=OperationModel(2.0)),
        # paper: cost factor 1.0, Explore 10 s with a 30 m radius; speed invented
        "bebop": RobotModel(cost_factor=1.0, speed_mps=3.0, explore=OperationModel(10.0, 30.0)),
    }


def load_team(path: str | Path) -> dict[str, RobotModel]:
    """Read a team file (YAML or JSON) of robot models."""
    file = Path(path)
    try:
        text = file.read_bytes()
    except OSError as exc:
        raise TeamFileError(f"{file}: cannot read ({exc.strerror})") from None
    try:
        if file.suffix in (".yaml", ".yml"):
            team = msgspec.yaml.decode(text, type=TeamFile)
        else:
            team = msgspec.json.decode(text, type=TeamFile)
    except msgspec.ValidationError as exc:
        raise TeamFileError(f"{file}: {exc}") from None
    except msgspec.DecodeError as exc:
        raise TeamFileError(f"{file}: not valid YAML/JSON ({exc})") from None
    for name, m in team.models.items():
        if m.cost_factor <= 0 or m.speed_mps <= 0:
            raise TeamFileError(f"{file}: models.{name}: cost_factor and speed_mps must be > 0")
        for op in ("explore", "identify", "decontaminate"):
            o = getattr(m, op)
            if o is not None and (o.duration_s < 0 or o.radius_m < 0):
                raise TeamFileError(f"{file}: models.{name}.{op}: durations and radii must be >= 0")
        if m.explore is not None and m.explore.radius_m <= 0:
            raise TeamFileError(f"{file}: models.{name}.explore.radius_m: expected > 0")
    return team.models
