"""Capability interfaces and implementations declared in files (YAML or JSON).

An interface file lists interfaces::

    btcap_interfaces: 1
    interfaces:
      - name: Echo
        description: Echo an integer back every tick.
        inputs: {value: int, stop: "bool | None"}
        outputs: {value: int}

An implementation file names the interface, its tree file (whose bridges are the node
types ``<Interface>Inputs`` / ``<Interface>Outputs``), optional preconditions, a constant
``cost`` and optionally a ``bid`` function (``"package.module:function"`` taking the
inputs and returning a cost or None)::

    btcap_implementation: 1
    name: echo-fast
    interface: Echo
    tree: echo_impl.yaml
    preconditions: [{capability: Calibrate, scope: local}]
    cost: 2.0

``bid`` may instead declare a distance bid, priced by the ROS bridge of an agent whose
file has a ``ros:`` block: ``factor`` x the straight-line distance from the robot's latest
pose on a topic (in its namespace) to an input; no pose yet (or one older than
``max_age_s``): the robot does not bid. ``function`` adds a function's term as above::

    bid:
      distance_from: {topic: pose, type: geometry_msgs/msg/PoseStamped, max_age_s: 5.0}
      to: goal
      factor: 2.0
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

from btcap.bt.files.load import tree_builder
from btcap.bt.ports import Port
from btcap.bt.registry import NodeRegistry, default_registry
from btcap.bt.state import TreeError
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import BidFunction, Implementation, Precondition
from btcap.team.capabilities.loader import load_callable

__all__ = [
    "CapabilityFileError",
    "DistanceBid",
    "FileBid",
    "load_implementation",
    "load_interfaces",
    "register_interfaces",
]


class CapabilityFileError(TreeError):
    """An interface or implementation file is invalid; names the file and the field."""


class _InterfaceSpec(msgspec.Struct, forbid_unknown_fields=True):
    name: str
    description: str = ""
    inputs: dict[str, str] = {}
    outputs: dict[str, str] = {}
    options: dict[str, Any] = {}


class _InterfaceFile(msgspec.Struct, forbid_unknown_fields=True):
    btcap_interfaces: int
    interfaces: list[_InterfaceSpec]


class _DistanceFrom(msgspec.Struct, forbid_unknown_fields=True):
    topic: str = "pose"
    type: str = "geometry_msgs/msg/PoseStamped"
    max_age_s: float | None = None


class _BidSpec(msgspec.Struct, forbid_unknown_fields=True):
    distance_from: _DistanceFrom
    to: str
    factor: float = 1.0
    function: str | None = None


#: A message type as the ROS bridge names them (``pkg/msg/Name``, or ``pkg/Name``).
_MSG_TYPE = re.compile(r"^[a-z][a-z0-9_]*/(msg/)?[A-Z][A-Za-z0-9]*$")


@dataclass(frozen=True, slots=True)
class DistanceBid:
    """A distance bid declared in an implementation file (see the module docstring);
    ``where`` names the file for the bridge's errors."""

    topic: str
    type: str
    to: str
    factor: float
    max_age_s: float | None
    where: str


class FileBid:
    """An implementation file's bid: its ``cost`` plus its function's term. A declared
    :attr:`distance` is the ROS bridge's to price (``btcap.ros`` wraps the
    implementation); unpriced, the robot does not bid."""

    __slots__ = ("cost", "distance", "function")

    def __init__(
        self, cost: float, function: BidFunction | None, distance: DistanceBid | None
    ) -> None:
        self.cost = cost
        self.function = function
        self.distance = distance

    def __call__(self, inputs: Mapping[str, Any]) -> float | None:
        if self.distance is not None:
            return None  # not priced: no bridge wrapped this implementation
        more = self.function(inputs) if self.function is not None else 0.0
        return None if more is None else self.cost + float(more)

    def without_distance(self) -> FileBid:
        """This bid but its distance term (the bridge adds that)."""
        return FileBid(self.cost, self.function, None)


class _ImplementationFile(msgspec.Struct, forbid_unknown_fields=True):
    btcap_implementation: int
    name: str
    interface: str
    tree: str
    preconditions: list[Precondition] = []
    cost: float = 0.0
    bid: str | _BidSpec | None = None


def _decode(path: Path, kind: type[Any]) -> Any:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CapabilityFileError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        if path.suffix in (".yaml", ".yml"):
            return msgspec.yaml.decode(data, type=kind)
        if path.suffix == ".json":
            return msgspec.json.decode(data, type=kind)
    except msgspec.ValidationError as exc:
        raise CapabilityFileError(f"{path}: {exc}") from None
    except msgspec.DecodeError as exc:
        raise CapabilityFileError(f"{path}: not valid YAML/JSON ({exc})") from None
    raise CapabilityFileError(f"{path}: expected a .yaml, .yml or .json file")


def load_interfaces(
    path: str | Path, registry: NodeRegistry | None = None
) -> list[CapabilityInterface]:
    """Read interfaces; port types are parsed by the registry's type parser."""
    file = Path(path)
    spec: _InterfaceFile = _decode(file, _InterfaceFile)
    if spec.btcap_interfaces != 1:
        raise CapabilityFileError(
            f"{file}: btcap_interfaces: version {spec.btcap_interfaces}; expected 1"
        )
    reg = registry or default_registry(plugins=False)
    out: list[CapabilityInterface] = []
    for i, s in enumerate(spec.interfaces):
        where = f"{file}: interfaces[{i}] ({s.name})"

        def ports(kind: str, given: Mapping[str, str], where: str = where) -> dict[str, Port]:
            result: dict[str, Port] = {}
            for key, text in given.items():
                try:
                    result[key] = Port(reg.parse_type(text))
                except TreeError as exc:
                    raise CapabilityFileError(f"{where}.{kind}.{key}: {exc}") from None
            return result

        try:
            out.append(
                CapabilityInterface(
                    s.name,
                    inputs=ports("inputs", s.inputs),
                    outputs=ports("outputs", s.outputs),
                    description=s.description,
                    options=s.options,
                )
            )
        except TreeError as exc:
            raise CapabilityFileError(f"{where}: {exc}") from None
    names = [i.name for i in out]
    if len(set(names)) != len(names):
        raise CapabilityFileError(f"{file}: interfaces: names must be unique, got {names}")
    return out


def register_interfaces(registry: NodeRegistry, interfaces: Iterable[CapabilityInterface]) -> None:
    """Make ``<Name>``, ``<Name>Inputs`` and ``<Name>Outputs`` usable in tree files."""
    for iface in interfaces:
        inputs, outputs = iface.bridge_types()
        for cls in (iface.node_type(), inputs, outputs):
            if cls.__name__ not in registry:
                registry.register(cls)


def _load_bid(ref: str, where: str) -> BidFunction:
    try:
        return load_callable(ref)
    except ValueError as exc:
        raise CapabilityFileError(f"{where}: bid: {exc}") from None


def load_implementation(
    path: str | Path,
    interfaces: Iterable[CapabilityInterface],
    registry: NodeRegistry | None = None,
) -> Implementation:
    """Read an implementation; its tree is loaded afresh for every execution."""
    file = Path(path)
    spec: _ImplementationFile = _decode(file, _ImplementationFile)
    where = str(file)
    if spec.btcap_implementation != 1:
        raise CapabilityFileError(
            f"{where}: btcap_implementation: version {spec.btcap_implementation}; expected 1"
        )
    known = {i.name: i for i in interfaces}
    iface = known.get(spec.interface)
    if iface is None:
        raise CapabilityFileError(
            f"{where}: interface: {spec.interface!r}; known: {', '.join(sorted(known)) or 'none'}"
        )
    reg = registry or default_registry(plugins=False)
    register_interfaces(reg, known.values())
    tree_path = (file.parent / spec.tree).resolve()
    try:
        build = tree_builder(tree_path, reg)  # read and parsed once, built for every run
        build()  # fail now, naming the files, rather than at the first award
    except TreeError as exc:
        raise CapabilityFileError(f"{where}: tree: {exc}") from None
    bid = _file_bid(spec, iface, where)
    return Implementation(spec.name, iface, build, preconditions=tuple(spec.preconditions), bid=bid)


def _file_bid(spec: _ImplementationFile, iface: CapabilityInterface, where: str) -> FileBid:
    given = spec.bid
    if given is None or isinstance(given, str):
        return FileBid(spec.cost, _load_bid(given, where) if given else None, None)
    d = given.distance_from
    if given.to not in iface.inputs:
        inputs = ", ".join(iface.inputs) or "none"
        raise CapabilityFileError(
            f"{where}: bid.to: {given.to!r} is not an input of {iface.name} (inputs: {inputs})"
        )
    if not (given.factor >= 0 and given.factor != float("inf")):
        raise CapabilityFileError(f"{where}: bid.factor: {given.factor}; expected a number >= 0")
    if not d.topic:
        raise CapabilityFileError(f"{where}: bid.distance_from.topic: expected a topic name")
    if not _MSG_TYPE.match(d.type):
        raise CapabilityFileError(
            f"{where}: bid.distance_from.type: {d.type!r}; expected a message type "
            "'package/msg/Name' (geometry_msgs/msg/PoseStamped)"
        )
    if d.max_age_s is not None and not d.max_age_s > 0:
        raise CapabilityFileError(
            f"{where}: bid.distance_from.max_age_s: {d.max_age_s}; expected seconds > 0"
        )
    function = _load_bid(given.function, where) if given.function else None
    distance = DistanceBid(d.topic, d.type, given.to, given.factor, d.max_age_s, where)
    return FileBid(spec.cost, function, distance)
