"""Robot models (what each kind of robot can do, how fast, at what cost) and team files."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import msgspec

from btcap.errors import BtcapError
from btcap.team.filecheck import field_first, not_finite

__all__ = ["OperationModel", "RobotModel", "TeamFile", "TeamFileError", "load_team", "paper_team"]


class TeamFileError(BtcapError, ValueError):
    """A team file is invalid; the message names the file and the field."""


class OperationModel(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """One sim operation a robot can perform: mean duration and, for explore, a radius."""

    duration_s: Annotated[
        float,
        msgspec.Meta(ge=0, description="How long the operation takes on average (seconds)."),
    ]
    radius_m: Annotated[
        float,
        msgspec.Meta(
            ge=0, description="For `explore`: how far around the robot it reveals (metres; > 0)."
        ),
    ] = 0.0


class RobotModel(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """A kind of robot; the paper's table gives durations, radii and cost factors."""

    cost_factor: Annotated[
        float,
        msgspec.Meta(
            gt=0, description="What a metre of driving costs in its bids (path length x factor)."
        ),
    ]
    speed_mps: Annotated[
        float, msgspec.Meta(gt=0, description="How fast it drives (metres per second).")
    ] = 1.0
    explore: Annotated[
        OperationModel | None,
        msgspec.Meta(description="Explore: reveal objects and new goals; null: cannot."),
    ] = None
    identify: Annotated[
        OperationModel | None,
        msgspec.Meta(description="Identify whether an object is contaminated; null: cannot."),
    ] = None
    decontaminate: Annotated[
        OperationModel | None,
        msgspec.Meta(
            description="Carry a contaminated object to the decontamination area; null: cannot."
        ),
    ] = None
    bids_from_here: Annotated[
        bool,
        msgspec.Meta(
            description="Price every bid from where the robot stands, also one for after the "
            "work it holds (a bid function that never asks `bidding_after()`, as a "
            "capability author may write it; the framework then bounds the later cost "
            "itself). For benches; false: from where that work leaves the robot."
        ),
    ] = False

    def can(self, op: str) -> bool:
        return getattr(self, op) is not None

    def operation(self, op: str) -> OperationModel:
        model: OperationModel | None = getattr(self, op, None)
        if model is None:
            raise ValueError(f"this robot model cannot {op}")
        return model


class TeamFile(msgspec.Struct, forbid_unknown_fields=True):
    """Robot models by name, for a scenario's ``team_file``."""

    models: Annotated[
        dict[str, RobotModel],
        msgspec.Meta(min_length=1, description="Robot models by the name robots give as `model`."),
    ]


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
        raw = (
            msgspec.yaml.decode(text)
            if file.suffix in (".yaml", ".yml")
            else msgspec.json.decode(text)
        )
    except msgspec.DecodeError as exc:
        raise TeamFileError(f"{file}: not valid YAML/JSON ({exc})") from None
    try:
        team = msgspec.convert(raw, TeamFile)
    except msgspec.ValidationError as exc:
        raise TeamFileError(f"{file}: {field_first(_named(str(exc), raw), TeamFile)}") from None
    if (why := not_finite(team)) is not None:
        raise TeamFileError(f"{file}: {why[0]}: {why[1]}")
    for name, m in team.models.items():
        if m.explore is not None and m.explore.radius_m <= 0:
            raise TeamFileError(f"{file}: models.{name}.explore.radius_m: expected > 0")
    return team.models


def _named(message: str, raw: object) -> str:
    """msgspec names a model ``$.models[...]``: put the model's name in its place."""
    models = raw.get("models") if isinstance(raw, dict) else None
    if "$.models[...]" not in message or not isinstance(models, dict):
        return message
    for name, entry in models.items():
        try:
            msgspec.convert(entry, RobotModel)
        except msgspec.ValidationError:
            return message.replace("$.models[...]", f"$.models.{name}")
    return message
