"""What starts one robot in a launch process, checked before any process is started.

Shared by the parent side (:mod:`btcap.team.deployment.spawn`) and the child side
(:mod:`btcap.team.deployment.launch`), so a bad spec fails in the parent with the same message the
child would print.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import msgspec

from btcap.team.filecheck import field_first
from btcap.team.settings import AgentConfig
from btcap.transports import KeyPair, TeamKeys

__all__ = ["AgentSpec", "agent_config", "agent_keys", "check_specs"]


class AgentSpec(msgspec.Struct, forbid_unknown_fields=True):
    """Everything needed to start one robot in a child process.

    ``factory`` (``"package.module:function"``, called with the robot and
    ``factory_args``) returns the robot's implementations, or an object with
    ``implementations`` and ``actors``; ``registry`` names a function returning the
    :class:`~transports.MessageRegistry` it speaks; ``config`` holds
    :class:`~btcap.team.settings.AgentConfig` fields. ``keys`` (a secret certificate
    ``NAME.key_secret``) and ``trusted`` (a directory of the team's public ``NAME.key``
    files, this robot's included) turn on CURVE; both empty means a plain transport.
    """

    robot: str
    bind: str = "tcp://127.0.0.1:*"
    peers: dict[str, str] = {}
    factory: str = ""
    factory_args: dict[str, Any] = {}
    speedup: float = 1.0
    config: dict[str, float | bool | str | None] = {}
    log_level: str = "warning"
    registry: str = ""
    keys: str = ""
    trusted: str = ""


def agent_config(spec: AgentSpec) -> AgentConfig:
    """The spec's ``config`` as an AgentConfig; ValueError naming an unknown key or a bad
    value."""
    try:
        return msgspec.convert(spec.config, AgentConfig)
    except msgspec.ValidationError as exc:
        raise ValueError(f"agent spec {spec.robot!r}: config: {field_first(str(exc))}") from None


def agent_keys(spec: AgentSpec) -> tuple[KeyPair | None, TeamKeys | None]:
    """The spec's CURVE key pair and allow-list, read from their files (None, None for a
    plain transport); ValueError naming the field that is missing or unreadable."""
    if not spec.keys and not spec.trusted:
        return None, None
    where = f"agent spec {spec.robot!r}"
    if not spec.keys or not spec.trusted:
        missing = "keys" if not spec.keys else "trusted"
        raise ValueError(f"{where}: {missing}: required with CURVE (keys and trusted go together)")
    try:
        pair = KeyPair.load(spec.keys)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{where}: keys: {exc}") from None
    try:
        team = TeamKeys.load(spec.trusted)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{where}: trusted: {exc}") from None
    if team.key_of(spec.robot) != pair.public:
        raise ValueError(
            f"{where}: trusted: {spec.trusted} holds no {spec.robot}.key matching keys "
            f"{spec.keys} (the team's directory must include this robot's public key)"
        )
    return pair, team


def check_specs(specs: Sequence[AgentSpec]) -> None:
    """The specs of one process: at least one, distinct robots, valid config, log level
    and key files."""
    if not specs:
        raise ValueError("no agent specs given")
    robots = [s.robot for s in specs]
    if len(set(robots)) != len(robots):
        raise ValueError(f"robot ids must differ within one process: {robots}")
    for s in specs:
        agent_config(s)
        agent_keys(s)
        if not isinstance(logging.getLevelName(s.log_level.upper()), int):
            raise ValueError(
                f"agent spec {s.robot!r}: log_level: {s.log_level!r}; "
                "expected debug, info, warning or error"
            )
