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
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import msgspec

from btcap.bt.files import load_tree
from btcap.bt.ports import Port
from btcap.bt.registry import NodeRegistry, default_registry
from btcap.bt.state import TreeError
from btcap.bt.tree import Tree
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import BidFunction, Implementation, Precondition
from btcap.team.capabilities.loader import load_callable

__all__ = [
    "CapabilityFileError",
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


class _ImplementationFile(msgspec.Struct, forbid_unknown_fields=True):
    btcap_implementation: int
    name: str
    interface: str
    tree: str
    preconditions: list[Precondition] = []
    cost: float = 0.0
    bid: str | None = None


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

    def build() -> Tree:
        return load_tree(tree_path, reg)

    try:
        build()  # fail now, naming the files, rather than at the first award
    except TreeError as exc:
        raise CapabilityFileError(f"{where}: tree: {exc}") from None
    extra = _load_bid(spec.bid, where) if spec.bid else None
    cost = spec.cost

    def bid(inputs: Mapping[str, Any]) -> float | None:
        more = extra(inputs) if extra is not None else 0.0
        return None if more is None else cost + float(more)

    return Implementation(spec.name, iface, build, preconditions=tuple(spec.preconditions), bid=bid)
