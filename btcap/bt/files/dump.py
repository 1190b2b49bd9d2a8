"""Dumping Trees to tree files: the document, its YAML/JSON text, and saving to a path.

What is written per node comes from :func:`btcap.bt.describe.describe`, the same
description the renderers show: options and inputs equal to their defaults are left
out, wired inputs are written as wires.
"""

from __future__ import annotations

import os
import typing
from collections.abc import Collection, Iterable
from pathlib import Path
from typing import Any

import msgspec
import msgspec.json
import yaml

from btcap.bt.describe import InputKey, describe, wire_sources
from btcap.bt.files.parse import format_of
from btcap.bt.files.schema import (
    SCHEMA_VERSION,
    Format,
    NodeSpec,
    PublicSpec,
    SubtreeSpec,
    TreeFile,
    TreeFileError,
    WireSpec,
    file_info,
    is_type_option,
)
from btcap.bt.node import Node
from btcap.bt.registry import NodeRegistry, RegistryError, default_registry
from btcap.bt.tree import Subtree, Tree

__all__ = ["dump_tree", "dumps_tree", "save_tree"]


def _lists(value: Any) -> Any:
    """Tuples as lists, as a file would give them back (so dumps compare equal)."""
    if isinstance(value, list | tuple):
        return [_lists(v) for v in value]
    if isinstance(value, dict):
        return {k: _lists(v) for k, v in value.items()}
    return value


class _Dumper:
    def __init__(self, registry: NodeRegistry, base: Path | None) -> None:
        self.registry = registry
        self.base = base
        self.subtrees: dict[str, SubtreeSpec] = {}

    def fail(self, msg: str) -> typing.NoReturn:
        raise TreeFileError([f"<dump>: {msg}"])

    def encode(self, value: Any, loc: str) -> Any:
        try:
            return _lists(msgspec.to_builtins(value))
        except (TypeError, ValueError) as exc:
            self.fail(f"{loc}: value {value!r} cannot be written to a file ({exc})")

    def tree(self, tree: Tree, fed: Collection[InputKey]) -> tuple[NodeSpec, list[WireSpec]]:
        if tree.blackboard is not None and tree.blackboard.ports:
            self.fail(
                f"tree {tree.name!r} uses BehaviorTree.CPP blackboard entries "
                f"({', '.join(tree.blackboard.ports)}), which a btcap tree file cannot hold "
                f"(it wires one output to inputs); keep the XML file"
            )
        root = self.node(tree.root, wire_sources(tree), fed)
        wires = [
            WireSpec(f"{w.source.path}.{w.source_port}", f"{w.target.path}.{w.target_port}")
            for w in tree.wires
        ]
        return root, wires

    def node(self, n: Node, wires: dict[InputKey, str], fed: Collection[InputKey]) -> NodeSpec:
        loc = f"node {n.path!r}"
        about = describe(n, wires, fed=fed)
        options: dict[str, Any] = {}
        if isinstance(n, Subtree):
            tname = "Subtree"
            options["tree"] = self.subtree(n)
        else:
            try:
                tname = self.registry.name_of(type(n))
            except RegistryError as exc:
                self.fail(f"{loc} field 'type': {exc}")
            cls = type(n)
            for key, value in about.options.items():
                if is_type_option(cls, key, cls.OPTIONS[key]):
                    try:
                        options[key] = self.registry.format_type(value)
                    except RegistryError as exc:
                        self.fail(f"{loc} option {key!r}: {exc}")
                else:
                    options[key] = self.encode(value, f"{loc} option {key!r}")
        inputs = {
            key: self.encode(value, f"{loc} input {key!r}") for key, value in about.inputs.items()
        }
        children = [self.node(c, wires, fed) for c in n.children]
        return NodeSpec(type=tname, name=n.name, options=options, inputs=inputs, children=children)

    def subtree(self, n: Subtree) -> str:
        inner = n.inner
        info = file_info(inner)
        if info.source is not None:
            ref = info.source
            if self.base is not None:
                ref = Path(os.path.relpath(info.source, self.base.resolve()))
            spec = SubtreeSpec(file=ref.as_posix())
        else:
            in_map: dict[str, tuple[Node, str]] = n._in_map
            out_map: dict[str, tuple[Node, str]] = n._out_map
            public = PublicSpec(
                inputs={k: f"{node.path}.{p}" for k, (node, p) in in_map.items()},
                outputs={k: f"{node.path}.{p}" for k, (node, p) in out_map.items()},
            )
            fed = {(id(node), p) for node, p in in_map.values()}
            root, wires = self.tree(inner, fed)
            spec = SubtreeSpec(
                description=info.description,
                root=root,
                wires=wires,
                public=public if public.inputs or public.outputs else None,
            )
        name, k = inner.name, 2
        while name in self.subtrees and self.subtrees[name] != spec:
            name, k = f"{inner.name}_{k}", k + 1
        self.subtrees[name] = spec
        return name


def dump_tree(
    tree: Tree,
    registry: NodeRegistry | None = None,
    *,
    base: str | os.PathLike[str] | None = None,
) -> TreeFile:
    """The :class:`TreeFile` describing ``tree``; ``base`` makes subtree file refs relative.

    Options and inputs equal to their defaults are left out; wired inputs are written
    as wires, never as values.
    """
    d = _Dumper(
        registry if registry is not None else default_registry(), Path(base) if base else None
    )
    root, wires = d.tree(tree, ())
    info = file_info(tree)
    return TreeFile(
        btcap=SCHEMA_VERSION,
        name=tree.name,
        description=info.description,
        root=root,
        wires=wires,
        subtrees=dict(sorted(d.subtrees.items())),
        public=info.public if info.public and (info.public.inputs or info.public.outputs) else None,
    )


class _YamlDumper(yaml.SafeDumper):
    """Block style for structure, flow style for short flat lists and mappings."""


def _flat(values: Iterable[Any]) -> bool:
    return all(v is None or isinstance(v, (str, int, float, bool)) for v in values)


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = _flat(data) and len(repr(data)) <= 60
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


def _represent_dict(dumper: yaml.SafeDumper, data: dict[Any, Any]) -> yaml.Node:
    flow = _flat(data.values()) and len(repr(data)) <= 72
    return dumper.represent_mapping("tag:yaml.org,2002:map", data.items(), flow_style=flow)


_YamlDumper.add_representer(list, _represent_list)
_YamlDumper.add_representer(dict, _represent_dict)


def dumps_tree(
    tree: Tree | TreeFile,
    fmt: Format = "yaml",
    registry: NodeRegistry | None = None,
    *,
    base: str | os.PathLike[str] | None = None,
) -> str:
    """The file text for a tree (or an already dumped :class:`TreeFile`)."""
    spec = tree if isinstance(tree, TreeFile) else dump_tree(tree, registry, base=base)
    if fmt == "json":
        return msgspec.json.format(msgspec.json.encode(spec), indent=2).decode() + "\n"
    if fmt != "yaml":
        raise ValueError(f"format {fmt!r}: expected 'yaml' or 'json'")
    data = msgspec.to_builtins(spec)
    return yaml.dump(data, Dumper=_YamlDumper, sort_keys=False, allow_unicode=True, width=100)


def save_tree(
    tree: Tree,
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
) -> Path:
    """Write ``tree`` to ``path``, YAML or JSON by suffix; returns the path."""
    p = Path(path)
    fmt = format_of(p)
    text = dumps_tree(tree, fmt, registry, base=p.parent)
    try:
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise TreeFileError([f"{p}: cannot write: {exc.strerror or exc}"]) from None
    return p
