"""Loading trees from files or text: the public entry points of reading."""

from __future__ import annotations

import os
import typing
from pathlib import Path

from btcap.bt.files.build import Builder
from btcap.bt.files.parse import decode, format_of, parse, read_bytes
from btcap.bt.files.schema import Format, TreeFileError
from btcap.bt.registry import NodeRegistry, default_registry
from btcap.bt.tree import Tree

if typing.TYPE_CHECKING:
    from btcap.actors import TimeSource

__all__ = ["load_tree", "loads_tree", "validate_file"]


def _load(
    data: bytes | str,
    fmt: Format,
    where: str,
    registry: NodeRegistry | None,
    clock: TimeSource | None,
    base: Path | None,
    source: Path | None,
) -> Tree:
    spec = parse(decode(data, fmt, where), where)
    reg = registry if registry is not None else default_registry()
    stack = (source.resolve(),) if source is not None else ()
    return Builder(spec, where, reg, base, stack, {}).build_main(clock)


def load_tree(
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
) -> Tree:
    """Build the tree a ``.yaml``/``.yml``/``.json`` file describes; raises TreeFileError."""
    p = Path(path)
    return _load(read_bytes(p), format_of(p), str(p), registry, clock, p.parent, p)


def loads_tree(
    text: str | bytes,
    fmt: Format = "yaml",
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
    name: str = "<string>",
    base: str | os.PathLike[str] | None = None,
) -> Tree:
    """Like :func:`load_tree` for text; ``name`` labels errors, ``base`` resolves file refs."""
    if fmt not in ("yaml", "json"):
        raise ValueError(f"format {fmt!r}: expected 'yaml' or 'json'")
    return _load(text, fmt, name, registry, clock, Path(base) if base else None, None)


def validate_file(path: str | os.PathLike[str], registry: NodeRegistry | None = None) -> list[str]:
    """Every problem of a file (empty if it loads); never raises for a bad file."""
    try:
        load_tree(path, registry)
    except TreeFileError as exc:
        return exc.problems
    return []
