"""Loading trees from files or text: the public entry points of reading."""

from __future__ import annotations

import os
import typing
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

from btcap.bt.files.board import Boards
from btcap.bt.files.btcpp import XmlTranslator
from btcap.bt.files.btcpp_doc import XmlOptions
from btcap.bt.files.btcpp_lines import relabel
from btcap.bt.files.btcpp_uses import set_entry_uses
from btcap.bt.files.build import Builder
from btcap.bt.files.parse import decode, format_of, parse, read_bytes
from btcap.bt.files.schema import TreeFileError
from btcap.bt.files.xmlread import read_xml
from btcap.bt.registry import NodeRegistry, default_registry
from btcap.bt.tree import Tree

if typing.TYPE_CHECKING:
    from btcap.actors import TimeSource

__all__ = ["TreeFileWarning", "load_tree", "loads_tree", "tree_builder", "validate_file"]


class TreeFileWarning(UserWarning):
    """A file btcap reads although it is not quite right (BehaviorTree.CPP warns too)."""


#: The model files (``--model``) and stub script (``--stub-script``) keywords take.
ModelFiles = Sequence[str | os.PathLike[str]]
StubScript = str | os.PathLike[str] | Mapping[str, Any] | None

#: What :func:`loads_tree` reads: btcap's own schema as YAML or JSON, or
#: BehaviorTree.CPP v4 XML (see :mod:`btcap.bt.files.btcpp`).
LoadFormat = Literal["yaml", "json", "xml"]


def _load(
    data: bytes | str,
    fmt: LoadFormat,
    where: str,
    registry: NodeRegistry | None,
    clock: TimeSource | None,
    base: Path | None,
    source: Path | None,
    options: XmlOptions,
    entries: Mapping[str, Any] | None = None,
) -> Tree:
    reg = registry if registry is not None else default_registry()
    stack = (source.resolve(),) if source is not None else ()
    if fmt != "xml" and entries:
        raise TreeFileError(
            [
                f"{where}: blackboard entries ({', '.join(entries)}) are for BehaviorTree.CPP "
                f"XML trees; a btcap tree file wires its inputs (or makes them public)"
            ]
        )
    if fmt != "xml":
        try:
            spec = parse(decode(data, fmt, where), where)
            return Builder(spec, where, reg, base, stack, {}).build_main(clock)
        except RecursionError:  # decoding, checking and building all recurse per level
            raise TreeFileError([f"{where}: nodes nested too deep to read"]) from None
    translator = XmlTranslator(
        read_xml(data, where), where, reg, options, base, source, entries or ()
    )
    try:
        spec = translator.translate()
    finally:
        for text in translator.warnings:
            warnings.warn(text, TreeFileWarning, stacklevel=4)
    boards = Boards(
        translator.boards, translator.main, entries or {}, translator.registry.script_enums
    )
    try:
        tree = Builder(spec, where, translator.registry, base, stack, {}, boards).build_main(clock)
    except TreeFileError as exc:
        raise TreeFileError(relabel(exc.problems, where, translator)) from None
    set_entry_uses(tree, translator.uses)
    return tree


def _format(path: Path) -> LoadFormat:
    return "xml" if path.suffix.lower() == ".xml" else format_of(path)


def load_tree(
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
    main: str | None = None,
    stub_missing: bool = False,
    models: ModelFiles = (),
    stub_script: StubScript = None,
    entries: Mapping[str, Any] | None = None,
) -> Tree:
    """Build the tree a ``.yaml``/``.yml``/``.json`` file describes; raises TreeFileError.

    A ``.xml`` file is read as BehaviorTree.CPP v4 XML (:mod:`btcap.bt.files.btcpp`):
    ``main`` picks its BehaviorTree to run, ``stub_missing`` builds the types its
    ``<TreeNodesModel>`` (or the ``models`` files) declare and nobody registered,
    returning what ``stub_script`` says (:mod:`btcap.bt.files.btcpp_stubs`). What
    BehaviorTree.CPP only warns about is a :class:`TreeFileWarning`. ``entries`` are
    blackboard entries the application supplies, as BehaviorTree.CPP's
    ``tree.rootBlackboard()->set(key, value)`` before ticking (text is converted to the
    entry's type); they can also be set later, before the first tick, through
    ``tree.blackboard``.
    """
    p = Path(path)
    opts = XmlOptions(main, stub_missing, tuple(models), stub_script)
    return _load(read_bytes(p), _format(p), str(p), registry, clock, p.parent, p, opts, entries)


def tree_builder(
    path: str | os.PathLike[str], registry: NodeRegistry | None = None
) -> Callable[[], Tree]:
    """What builds the tree ``path`` describes, again and again, the file read and parsed
    once, now (raises TreeFileError if it does not parse): a capability implementation's
    tree is built for every run, and reading and parsing is most of what that costs
    (YAML: about 60 %). Files it refers to are read at the first build and kept. A
    BehaviorTree.CPP ``.xml`` file is read at every build (:func:`load_tree`)."""
    p = Path(path)
    fmt = _format(p)
    if fmt == "xml":
        return lambda: load_tree(p, registry)
    reg = registry if registry is not None else default_registry()
    where, stack = str(p), (p.resolve(),)
    cache: dict[Path, Any] = {}
    try:
        spec = parse(decode(read_bytes(p), fmt, where), where)
    except RecursionError:
        raise TreeFileError([f"{where}: nodes nested too deep to read"]) from None

    def build() -> Tree:
        try:
            return Builder(spec, where, reg, p.parent, stack, cache).build_main(None)
        except RecursionError:
            raise TreeFileError([f"{where}: nodes nested too deep to read"]) from None

    return build


def loads_tree(
    text: str | bytes,
    fmt: LoadFormat = "yaml",
    registry: NodeRegistry | None = None,
    *,
    clock: TimeSource | None = None,
    name: str = "<string>",
    base: str | os.PathLike[str] | None = None,
    main: str | None = None,
    stub_missing: bool = False,
    models: ModelFiles = (),
    stub_script: StubScript = None,
    entries: Mapping[str, Any] | None = None,
) -> Tree:
    """Like :func:`load_tree` for text; ``name`` labels errors, ``base`` resolves file refs."""
    if fmt not in ("yaml", "json", "xml"):
        raise ValueError(f"format {fmt!r}: expected 'yaml', 'json' or 'xml'")
    opts = XmlOptions(main, stub_missing, tuple(models), stub_script)
    folder = Path(base) if base else None
    return _load(text, fmt, name, registry, clock, folder, None, opts, entries)


def validate_file(
    path: str | os.PathLike[str],
    registry: NodeRegistry | None = None,
    *,
    main: str | None = None,
    stub_missing: bool = False,
    models: ModelFiles = (),
    stub_script: StubScript = None,
) -> list[str]:
    """Every problem of a file (empty if it loads); never raises for a bad file."""
    try:
        load_tree(
            path,
            registry,
            main=main,
            stub_missing=stub_missing,
            models=models,
            stub_script=stub_script,
        )
    except TreeFileError as exc:
        return exc.problems
    return []
