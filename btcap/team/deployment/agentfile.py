"""The schema of an agent file (``btcap agent CONFIG``): its msgspec types, each field
with its meaning and bounds, so msgspec refuses a bad value naming the field and the file
reference (``btcap schema agent``, docs/files.md) is generated from them.

:mod:`btcap.team.deployment.agentconfig` reads the file and checks what the types cannot say. The
``timing`` and ``allocation`` blocks are the settings of :mod:`btcap.team.settings`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec

from btcap.team.rossettings import RosSettings
from btcap.team.settings import Allocation, Timing
from btcap.transports.newcomers import LINKS_PER_PEER

__all__ = [
    "AgentFile",
    "Allocation",
    "Capabilities",
    "FileTiming",
    "Keys",
    "Network",
    "Plugin",
    "RosSettings",
    "Seed",
    "Timing",
]


def _doc(text: str) -> msgspec.Meta:
    return msgspec.Meta(description=text)


class Seed(msgspec.Struct, forbid_unknown_fields=True):
    """A teammate to dial at start; the rest of the team is learnt from the seeds."""

    robot: Annotated[str, _doc("The teammate's robot name (not this robot's).")]
    endpoint: Annotated[
        str, _doc("Where it listens: a `tcp://HOST:PORT`, `ipc://PATH` or `inproc://` endpoint.")
    ]


class Network(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """Where the robot listens and whom it dials first."""

    bind: Annotated[
        str,
        _doc(
            "Where the robot listens: `tcp://HOST:PORT` (`*` for any free port), `ipc://PATH` "
            "or `inproc://NAME`. Without `keys`, only loopback, ipc and inproc addresses."
        ),
    ] = "tcp://127.0.0.1:*"
    advertise: Annotated[
        str | None,
        _doc(
            "The endpoint teammates dial; required when `bind` is a wildcard address "
            "(`tcp://0.0.0.0:7101`)."
        ),
    ] = None
    seeds: Annotated[
        list[Seed],
        _doc("Teammates dialled at start; one reachable seed is enough to join the team."),
    ] = []
    max_peers: Annotated[
        int, msgspec.Meta(gt=0, description="At most this many peers are kept.")
    ] = 1024
    hello_timeout_s: Annotated[
        float,
        msgspec.Meta(
            gt=0,
            description="Seconds an inbound connection may stay silent: every teammate "
            "says hello first, so one that says none in time is closed (it holds a file "
            "descriptor until then).",
        ),
    ] = 10.0
    max_newcomers: Annotated[
        int,
        msgspec.Meta(
            gt=0,
            description="At most this many inbound connections wait for their hello at "
            "once; beyond, the oldest is closed.",
        ),
    ] = 128
    links_per_peer: Annotated[
        int,
        msgspec.Meta(
            ge=2,
            description="Inbound connections kept per teammate (at least 2: one that "
            "reconnects holds two for a moment); beyond, the oldest is closed.",
        ),
    ] = LINKS_PER_PEER


class Keys(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """CURVE key files in ZeroMQ's certificate format (``btcap keys new``)."""

    secret: Annotated[
        Path,
        _doc(
            "This robot's secret certificate `NAME.key_secret` (it holds the public key "
            "too). Key paths may use environment variables (`${BTCAP_KEYS}/alpha.key_secret`)."
        ),
    ]
    trusted: Annotated[
        Path,
        _doc(
            "A directory of the team's public certificates `NAME.key`, this robot's "
            "included, each with its role (robot, operator or observer) in its metadata: "
            "only robots whose key is there get through the handshake, and each sends only "
            "what its role allows."
        ),
    ]


class Capabilities(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """Interface files, and the implementation files this robot runs (none: an operator)."""

    interfaces: Annotated[
        list[Path], _doc("Capability interface files the robot and its mission trees know.")
    ] = []
    implementations: Annotated[
        list[Path],
        _doc("Capability implementation files the robot runs; none for an operator."),
    ] = []


class Plugin(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """Python code the robot runs beside its capability files (a simulator's body, say)."""

    factory: Annotated[
        str,
        _doc(
            "`package.module:function`, called with the robot's name and `args`: returns "
            "implementations, or an object with `implementations` and `actors` (path -> "
            "actor spawned beside the runtime)."
        ),
    ]
    args: Annotated[dict[str, Any], _doc("Keyword arguments for `factory`.")] = {}
    messages: Annotated[
        str | None,
        _doc(
            "`package.module:function` returning the MessageRegistry the robot speaks "
            "(btcap's protocol and more); null: btcap's protocol."
        ),
    ] = None


class FileTiming(Timing, frozen=True):
    """Rates and timeouts (:class:`~btcap.team.settings.Timing`), plus the clock's speed-up."""

    speedup: Annotated[
        float,
        msgspec.Meta(
            gt=0,
            description="The clock's speed-up: clock seconds per wall second; "
            "every robot of a team runs at the same one.",
        ),
    ] = 1.0


class AgentFile(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """One robot's configuration file (``btcap agent CONFIG``)."""

    btcap: Annotated[Literal[1], _doc("The file format's version: 1.")]
    robot: Annotated[
        str,
        _doc("The robot's name in the team: non-empty, no `/`, not `*`, at most 240 bytes."),
    ]
    capabilities: Annotated[Capabilities, _doc("The capability files, relative to this file.")] = (
        msgspec.field(default_factory=Capabilities)
    )
    network: Annotated[Network, _doc("Where the robot listens and whom it dials.")] = msgspec.field(
        default_factory=Network
    )
    keys: Annotated[
        Keys | None,
        _doc("CURVE keys; null: unencrypted, and bound only where this host alone reaches it."),
    ] = None
    timing: Annotated[FileTiming, _doc("Rates and timeouts, and the clock's speed-up.")] = (
        msgspec.field(default_factory=FileTiming)
    )
    allocation: Annotated[Allocation, _doc("How work is allocated and moved.")] = msgspec.field(
        default_factory=Allocation
    )
    plugin: Annotated[
        Plugin | None, _doc("Python code run beside the capability files; null: none.")
    ] = None
    ros: Annotated[
        RosSettings | None,
        _doc(
            "The robot's ROS 2 node (docs/ros2.md); null: no ROS, and nothing of ROS is imported."
        ),
    ] = None
