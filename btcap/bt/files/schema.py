"""The tree file schema (version :data:`SCHEMA_VERSION`) and what a loaded Tree keeps of it."""

from __future__ import annotations

import copy
import dataclasses
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any, Literal

import msgspec

from btcap.bt.node import Node
from btcap.bt.ports import Port
from btcap.bt.state import TreeError
from btcap.bt.tree import Tree

__all__ = [
    "SCHEMA_VERSION",
    "STRUCT_FIELDS",
    "FileInfo",
    "Format",
    "NodeSpec",
    "PublicSpec",
    "SubtreeSpec",
    "TreeFile",
    "TreeFileError",
    "WireSpec",
    "file_info",
    "is_type_option",
    "literal",
    "set_file_info",
]

#: The schema version this btcap reads and writes (the ``btcap:`` key of every file).
SCHEMA_VERSION = 1

Format = Literal["yaml", "json"]
_INFO_ATTR = "file_info"


class TreeFileError(TreeError):
    """A tree file is invalid; ``problems`` lists every finding, each starting with the file."""

    def __init__(self, problems: Iterable[str]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


class NodeSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """One node: registered type, name (default: the type), options, inputs, children."""

    type: str
    name: str | None = None
    options: dict[str, Any] = {}
    inputs: dict[str, Any] = {}
    children: list[NodeSpec] = []


class WireSpec(msgspec.Struct, forbid_unknown_fields=True):
    """``from: node/path.output`` feeds ``to: node/path.input`` (paths start at the root)."""

    source: str = msgspec.field(name="from")
    target: str = msgspec.field(name="to")


class PublicSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """Ports a tree exposes when used as a subtree: public name -> ``node/path.port``."""

    inputs: dict[str, str] = {}
    outputs: dict[str, str] = {}


class SubtreeSpec(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """A named inner tree: inline (``root``, ``wires``, ``public``) or ``file: other.yaml``.

    A file path is relative to the file that names it; the other file's own ``public``
    section then says which ports the subtree exposes.
    """

    file: str | None = None
    description: str = ""
    root: NodeSpec | None = None
    wires: list[WireSpec] = []
    public: PublicSpec | None = None


class TreeFile(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True, kw_only=True):
    """A whole tree file (schema version :data:`SCHEMA_VERSION`)."""

    btcap: int
    name: str | None = None
    description: str = ""
    root: NodeSpec
    wires: list[WireSpec] = []
    subtrees: dict[str, SubtreeSpec] = {}
    public: PublicSpec | None = None


#: The fields of each schema struct as a file spells them, for "expected one of" hints.
STRUCT_FIELDS: dict[str, tuple[str, ...]] = {
    "file": ("btcap", "name", "description", "root", "wires", "subtrees", "public"),
    "subtree": ("file", "description", "root", "wires", "public"),
    "node": ("type", "name", "options", "inputs", "children"),
    "wire": ("from", "to"),
    "public": ("inputs", "outputs"),
}


@dataclasses.dataclass(frozen=True)
class FileInfo:
    """What a file says about a tree beyond its nodes; kept on the Tree for saving."""

    description: str = ""
    public: PublicSpec | None = None
    #: The file a subtree came from (it is saved as a reference to that file again).
    source: Path | None = None


def file_info(tree: Tree) -> FileInfo:
    """The :class:`FileInfo` a loaded tree carries (empty for trees built in code)."""
    info = getattr(tree, _INFO_ATTR, None)
    return info if isinstance(info, FileInfo) else FileInfo()


def set_file_info(tree: Tree, info: FileInfo) -> None:
    """Remember what the file said about ``tree``, so saving it writes the same again."""
    setattr(tree, _INFO_ATTR, info)


def is_type_option(cls: type[Node], key: str, port: Port) -> bool:
    """Options whose value is a type (Constant's ``type``) are written as type names.

    A node marks them with ``TYPE_OPTIONS = frozenset({...})``; otherwise an option
    declared as ``type`` or defaulting to a type (``Port(Any, Any)``) counts as one.
    """
    if key in getattr(cls, "TYPE_OPTIONS", ()):
        return True
    t, d = port.type, port.default
    if t is type or typing.get_origin(t) is type:
        return True
    return d is Any or isinstance(d, type) or typing.get_origin(d) is not None


def literal(value: Any) -> Any:
    """A file's value for one node: a list or mapping copied, since one parse of a file
    may build many trees (a capability implementation's, one per run) and a node may
    change what it was given (a port of type Any keeps the very object)."""
    return copy.deepcopy(value) if isinstance(value, list | dict) else value
