"""One robot's configuration file (``btcap agent CONFIG``), checked before anything starts.

A versioned YAML (or JSON) file; paths in it are relative to the file::

    btcap: 1
    robot: alpha
    capabilities:
      interfaces: [../capabilities/interfaces.yaml]
      implementations: [../capabilities/greet.yaml]
    network:
      bind: tcp://0.0.0.0:7001           # where to listen
      advertise: tcp://10.0.0.1:7001     # what peers dial (required for a wildcard bind)
      seeds: [{robot: beta, endpoint: tcp://10.0.0.2:7002}]
    keys: {secret: keys/alpha.key_secret, trusted: keys/team}
    timing: {tick_hz: 10, heartbeat_s: 0.1, failure_timeout_s: 0.5, lease_s: 0.8}
    allocation: {rebid_on_join: 0.25}
    plugin:                              # optional: Python code beside the files
      factory: mypkg.robots:make         # make(robot, **args): implementations (and actors)
      args: {model: husky}
      messages: mypkg.robots:registry    # the MessageRegistry it speaks

Every error is an :class:`AgentConfigError` naming the file and the field. Without
``keys`` the transport binds only a loopback (or ipc/inproc) address, unless the caller
explicitly allows an insecure bind.
"""

from __future__ import annotations

import inspect
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

from btcap.actors import Actor
from btcap.bt.registry import NodeRegistry
from btcap.bt.state import TreeError
from btcap.team.allocation.strategies import check_strategy
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.capfiles import (
    load_implementation,
    load_interfaces,
    register_interfaces,
)
from btcap.team.capabilities.implementation import Implementation
from btcap.team.capabilities.loader import load_callable
from btcap.team.deployment.agentfile import (
    AgentFile,
    Allocation,
    Capabilities,
    FileTiming,
    Keys,
    Network,
    Plugin,
    Seed,
    Timing,
)
from btcap.team.filecheck import field_first, not_finite
from btcap.team.runtime.protocol import protocol_registry
from btcap.team.settings import AgentConfig
from btcap.transports import MessageRegistry, ZmqTransport
from btcap.transports.identity import OBSERVER, check_member_name, is_observer_id, member_of
from btcap.transports.security import KeyPair, TeamKeys
from btcap.transports.zmq_endpoints import check_endpoint, check_id

__all__ = [
    "AgentConfigError",
    "AgentFile",
    "Allocation",
    "Capabilities",
    "FileTiming",
    "Keys",
    "Network",
    "Plugged",
    "Plugin",
    "RobotConfig",
    "Seed",
    "Timing",
    "load_agent_file",
]

_WILDCARDS = ("*", "0.0.0.0", "::", "[::]")


class AgentConfigError(TreeError):
    """An agent configuration file is invalid; the message names the file and the field."""


@dataclass(frozen=True, slots=True)
class Plugged:
    """What a plugin gave: implementations, actors and the messages spoken."""

    implementations: list[Implementation]
    actors: dict[str, Actor]
    messages: MessageRegistry


@dataclass(frozen=True, slots=True)
class RobotConfig:
    """A checked configuration file (paths resolved) and what it builds."""

    path: Path
    spec: AgentFile

    @property
    def robot(self) -> str:
        return self.spec.robot

    @property
    def network(self) -> Network:
        return self.spec.network

    @property
    def keys(self) -> Keys | None:
        return self.spec.keys

    @property
    def seeds(self) -> dict[str, str]:
        return {s.robot: s.endpoint for s in self.spec.network.seeds}

    def agent_config(self) -> AgentConfig:
        return AgentConfig.of(self.spec.timing, self.spec.allocation)

    def load_capabilities(
        self, registry: NodeRegistry, *, implementations: bool = True
    ) -> tuple[list[CapabilityInterface], list[Implementation]]:
        """The interfaces (registered in ``registry`` so tree files can use them) and, if
        asked, this robot's implementations; errors name this file, the field and the
        capability file."""
        caps = self.spec.capabilities
        interfaces: list[CapabilityInterface] = []
        for i, path in enumerate(caps.interfaces):
            try:
                interfaces.extend(load_interfaces(path, registry))
            except TreeError as exc:
                raise self.error(f"capabilities.interfaces[{i}]", str(exc)) from None
        register_interfaces(registry, interfaces)
        impls: list[Implementation] = []
        for i, path in enumerate(caps.implementations if implementations else []):
            try:
                impls.append(load_implementation(path, interfaces, registry))
            except TreeError as exc:
                raise self.error(f"capabilities.implementations[{i}]", str(exc)) from None
        return interfaces, impls

    def load_plugin(self, *, factory: bool = True) -> Plugged:
        """Run the plugin's factory (not for an observer: ``factory=False``) and load the
        messages it speaks; no plugin: btcap's protocol alone. Errors name the field."""
        plugin = self.spec.plugin
        if plugin is None:
            return Plugged([], {}, protocol_registry())
        impls: list[Implementation] = []
        actors: dict[str, Actor] = {}
        try:
            make = load_callable(plugin.factory)
        except ValueError as exc:
            raise self.error("plugin.factory", str(exc)) from None
        try:
            inspect.signature(make).bind(self.robot, **plugin.args)
        except TypeError as exc:
            raise self.error("plugin.args", str(exc)) from None
        if factory:
            made = make(self.robot, **plugin.args)
            if hasattr(made, "implementations"):
                impls, actors = list(made.implementations), dict(getattr(made, "actors", {}))
            else:
                impls = list(made)
        messages = protocol_registry()
        if plugin.messages is not None:
            try:
                messages = load_callable(plugin.messages)()
            except (ValueError, TypeError) as exc:
                raise self.error("plugin.messages", str(exc)) from None
            if not isinstance(messages, MessageRegistry):
                why = f"returned {type(messages).__name__}, expected a MessageRegistry"
                raise self.error("plugin.messages", why)
        return Plugged(impls, actors, messages)

    def transport(
        self,
        registry: MessageRegistry,
        *,
        robot: str | None = None,
        ephemeral: bool = False,
        insecure: bool = False,
    ) -> ZmqTransport:
        """A transport bound as configured (or, ``ephemeral``, on the same host with a port
        the system picks, for a short-lived observer beside a running robot) that dials
        the seeds. With keys it is CURVE-encrypted; without, it binds only where this host
        alone can reach it, unless ``insecure``."""
        net = self.spec.network
        bind, advertise = net.bind, net.advertise
        if ephemeral:
            bind, advertise = _ephemeral(bind, advertise, robot or self.robot), None
        keys: KeyPair | None = None
        trusted: TeamKeys | None = None
        if self.keys is not None:
            try:
                keys = KeyPair.load(self.keys.secret)
            except (OSError, ValueError) as exc:
                raise self.error("keys.secret", str(exc)) from None
            try:
                trusted = TeamKeys.load(self.keys.trusted)
            except (OSError, ValueError) as exc:
                raise self.error("keys.trusted", str(exc)) from None
            name = robot or self.robot
            if trusted.role_of(name) == OBSERVER and not is_observer_id(name):
                raise self.error(
                    "keys.secret",
                    f"{name}'s key has the role observer: it can only look at the team "
                    "(btcap team status), not join it",
                )
            as_other = robot is not None and not is_observer_id(name)
            self._check_trusted(member_of(name), bind, keys, trusted, as_other)
        try:
            return ZmqTransport(
                robot or self.robot,
                bind,
                registry,
                peers=self.seeds,
                max_peers=net.max_peers,
                hello_timeout_s=net.hello_timeout_s,
                max_newcomers=net.max_newcomers,
                links_per_peer=net.links_per_peer,
                advertise=advertise,
                keys=keys,
                trusted=trusted,
                insecure=insecure,
            )
        except ValueError as exc:
            if keys is None and not insecure and "without keys" in str(exc):
                raise self.error(
                    "network.bind",
                    f"{bind!r} can be reached from other hosts, and this file has no keys: "
                    "add keys: {secret: NAME.key_secret, trusted: DIR} (btcap keys new), "
                    "bind a loopback address, or run with --insecure",
                ) from None
            field = "keys" if keys is not None and "key" in str(exc) else "network.bind"
            raise self.error(field, str(exc)) from None

    def _check_trusted(
        self, robot: str, bind: str, keys: KeyPair, trusted: TeamKeys, as_other: bool
    ) -> None:
        """What CURVE would refuse, in this file's words (the transport's are Python's)."""
        assert self.keys is not None
        folder = self.keys.trusted
        named = f"robot {robot!r}" + (" (--as)" if as_other else "")
        if trusted.key_of(robot) is None:
            why = f"{folder} has no {robot}.key, so teammates would refuse {named}"
            raise self.error("keys.trusted", f"{why} (btcap keys new {robot}, then copy it)")
        if trusted.key_of(robot) != keys.public:
            raise self.error(
                "keys.secret",
                f"{self.keys.secret} is not the key of {named}: {folder}/{robot}.key holds "
                "another public key, so teammates would refuse it",
            )
        if bind.startswith("inproc://"):
            raise self.error(
                "network.bind",
                f"{bind!r}: inproc:// is not encrypted; with keys use ipc:// or tcp://",
            )
        for i, seed in enumerate(self.spec.network.seeds):
            if trusted.key_of(seed.robot) is None:
                why = f"{folder} (keys.trusted) has no {seed.robot}.key: we could not check it"
                raise self.error(f"network.seeds[{i}].robot", f"{seed.robot!r}: {why}")
            if seed.endpoint.startswith("inproc://"):
                why = "inproc:// is not encrypted; with keys use ipc:// or tcp://"
                raise self.error(f"network.seeds[{i}].endpoint", f"{seed.endpoint!r}: {why}")

    def error(self, field: str, why: str) -> AgentConfigError:
        return AgentConfigError(f"{self.path}: {field}: {why}")


def load_agent_file(path: str | Path) -> RobotConfig:
    """Read and check a configuration file; relative paths in it become absolute."""
    file = Path(path)
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise AgentConfigError(f"{file}: cannot read ({exc.strerror or exc})") from None
    try:
        raw = msgspec.json.decode(data) if file.suffix == ".json" else msgspec.yaml.decode(data)
    except msgspec.DecodeError as exc:
        raise AgentConfigError(f"{file}: not valid YAML/JSON ({exc})") from None
    if not isinstance(raw, dict):
        raise AgentConfigError(f"{file}: expected a mapping with 'btcap: 1' and 'robot'")
    version = raw.get("btcap")
    if version is not None and version != 1:
        raise AgentConfigError(f"{file}: btcap: version {version!r}; expected 1")
    try:
        spec = msgspec.convert(raw, AgentFile, dec_hook=_paths)
    except msgspec.ValidationError as exc:
        raise AgentConfigError(f"{file}: {field_first(str(exc), AgentFile)}") from None
    config = RobotConfig(file, spec)
    if (why := not_finite(spec)) is not None:
        raise config.error(*why)
    _check(config, file.parent)
    return config


def _paths(kind: type[Any], value: Any) -> Any:
    if kind is Path and isinstance(value, str):
        return Path(value)
    raise NotImplementedError


def _check(config: RobotConfig, base: Path) -> None:
    spec = config.spec
    try:
        check_strategy(spec.allocation.strategy)
    except ValueError as exc:
        raise config.error("allocation.strategy", str(exc)) from None
    if (why := check_id(spec.robot) or check_member_name(spec.robot)) is not None:
        raise config.error("robot", f"{spec.robot!r}: {why}")
    net = spec.network
    if (why := check_endpoint(net.bind, dial=False)) is not None:
        raise config.error("network.bind", f"{net.bind!r}: {why}")
    if net.advertise is not None:
        if (why := check_endpoint(net.advertise, dial=True)) is not None:
            raise config.error("network.advertise", f"{net.advertise!r}: {why}")
    elif _host(net.bind) in _WILDCARDS:
        raise config.error(
            "network.advertise",
            f"required when binding the wildcard address {net.bind!r}: "
            "the endpoint other hosts reach this robot at",
        )
    seen: set[str] = set()
    for i, seed in enumerate(net.seeds):
        if (why := check_id(seed.robot)) is not None:
            raise config.error(f"network.seeds[{i}].robot", f"{seed.robot!r}: {why}")
        if seed.robot == spec.robot:
            raise config.error(f"network.seeds[{i}].robot", f"{seed.robot!r} is this robot")
        if seed.robot in seen:
            raise config.error(f"network.seeds[{i}].robot", f"{seed.robot!r} is listed twice")
        seen.add(seed.robot)
        if (why := check_endpoint(seed.endpoint, dial=True)) is not None:
            raise config.error(f"network.seeds[{i}].endpoint", f"{seed.endpoint!r}: {why}")
    caps = spec.capabilities
    caps.interfaces = _files(config, base, "capabilities.interfaces", caps.interfaces)
    caps.implementations = _files(
        config, base, "capabilities.implementations", caps.implementations
    )
    if spec.keys is not None:
        _check_keys(config, spec.keys, base)


def _files(config: RobotConfig, base: Path, field: str, paths: list[Path]) -> list[Path]:
    out = []
    for i, path in enumerate(paths):
        full = (base / path).resolve()
        if not full.is_file():
            raise config.error(f"{field}[{i}]", f"{full}: no such file")
        out.append(full)
    return out


def _check_keys(config: RobotConfig, keys: Keys, base: Path) -> None:
    for name in ("secret", "trusted"):
        given = str(getattr(keys, name))
        expanded = os.path.expandvars(given)  # keys often live outside the repository
        if "$" in expanded:
            raise config.error(f"keys.{name}", f"{given}: an environment variable is not set")
        path = (base / expanded).resolve()
        want_dir = name == "trusted"
        if not (path.is_dir() if want_dir else path.is_file()):
            what = "directory" if want_dir else "file"
            raise config.error(f"keys.{name}", f"{path}: no such {what}")
        setattr(keys, name, path)


def _host(endpoint: str) -> str:
    if not endpoint.startswith("tcp://"):
        return ""
    netloc = endpoint[len("tcp://") :]
    host, _, _port = netloc.rpartition(":")
    return host


def _ephemeral(bind: str, advertise: str | None, robot: str) -> str:
    if bind.startswith("tcp://"):
        host = _host(bind)
        if host in _WILDCARDS and advertise is not None:
            host = _host(advertise)
        return f"tcp://{host}:*"
    return f"{bind}-{robot}"  # ipc:// and inproc:// name a path or a label
