"""The documents of a BehaviorTree.CPP XML tree: the file, its ``<include>``s, model files.

BehaviorTree.CPP loads a file's ``<BehaviorTree>``s, and those of every file it
``<include path="...">``s (relative to the including file), into one set of trees; a
``<BehaviorTree>`` without an ID is named ``BehaviorTree_0``, ``_1``... as it names
them. :class:`Documents` collects them with the file each came from, and the
``<TreeNodesModel>`` entries of all of them and of separate model files
(``--model nav2_tree_nodes.xml``).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from btcap.bt.files.btcpp_elements import MODEL_KINDS
from btcap.bt.files.parse import read_bytes
from btcap.bt.files.schema import TreeFileError
from btcap.bt.files.xmlread import XmlElement, read_xml

__all__ = ["Documents", "XmlOptions"]


@dataclasses.dataclass(frozen=True)
class XmlOptions:
    """How a BehaviorTree.CPP XML file is read (the ``load_tree`` keywords)."""

    #: The BehaviorTree to run; default: ``main_tree_to_execute``, or the only one.
    main: str | None = None
    #: Build a stand-in for every type ``<TreeNodesModel>`` declares but nobody registered.
    stub_missing: bool = False
    #: Model files (``<root><TreeNodesModel>...``) read besides the tree's own models.
    models: tuple[str | os.PathLike[str], ...] = ()
    #: Results of the stand-ins: a YAML file, or its content (:mod:`~.btcpp_stubs`).
    stub_script: str | os.PathLike[str] | Mapping[str, Any] | None = None


class Documents:
    """Every BehaviorTree and model of a file and what it includes, with their files."""

    def __init__(self, fail: Callable[[str, int, str], None], warn: Callable[[str], None]) -> None:
        self.fail = fail  # (file, line, message)
        self.warn = warn
        self.trees: dict[str, XmlElement] = {}
        self.models: dict[str, XmlElement] = {}
        self._anonymous = 0

    def root(self, root: XmlElement, where: str, *, model_file: bool = False) -> bool:
        """Whether ``root`` is a ``<root>`` of a format btcap reads (problems reported)."""
        if root.tag != "root":
            self.fail(where, root.line, f'<{root.tag}>: expected <root BTCPP_format="4">')
            return False
        fmt = root.attrs.get("BTCPP_format")
        if fmt is None:
            if not model_file:
                self.warn(
                    f"{where}: line {root.line}: <root> has no BTCPP_format; read as "
                    f'format 4 (BehaviorTree.CPP warns too): add BTCPP_format="4"'
                )
            return True
        if fmt == "3":
            self.fail(
                where,
                root.line,
                '<root> has BTCPP_format="3": BehaviorTree.CPP 3.x files name nodes and '
                "ports differently (SequenceStar, SubTreePlus, remapping); convert it to "
                "format 4 (Groot2 or BehaviorTree.CPP's convert_v3_to_v4.py) first",
            )
            return False
        if fmt != "4":
            self.fail(
                where,
                root.line,
                f"<root> has BTCPP_format={fmt!r}; btcap reads BehaviorTree.CPP format 4",
            )
            return False
        return True

    def read(
        self, root: XmlElement, where: str, folder: Path | None, chain: tuple[Path, ...]
    ) -> None:
        """Collect ``root``'s trees and models, following its includes."""
        for el in root.children:
            if el.tag == "BehaviorTree":
                self._tree(el, where)
            elif el.tag == "TreeNodesModel":
                self._models(el)
            elif el.tag == "include":
                self._include(el, where, folder, chain)
            else:
                self.fail(
                    where,
                    el.line,
                    f"<{el.tag}>: expected <BehaviorTree>, <TreeNodesModel> or <include>",
                )

    def model_file(self, path: str | os.PathLike[str]) -> None:
        """Read the ``<TreeNodesModel>`` of a separate model file."""
        p = Path(path)
        try:
            root = read_xml(read_bytes(p), str(p))
        except TreeFileError as exc:
            for problem in exc.problems:
                self.fail(str(p), 0, problem.removeprefix(f"{p}: "))
            return
        if not self.root(root, str(p), model_file=True):
            return
        found = False
        for el in root.children:
            if el.tag == "TreeNodesModel":
                found = True
                self._models(el)
        if not found:
            self.fail(str(p), root.line, "no <TreeNodesModel> in this model file")

    def _tree(self, el: XmlElement, where: str) -> None:
        tid = el.attrs.get("ID")
        if not tid:  # BehaviorTree.CPP names them so, in the order it reads them
            tid = f"BehaviorTree_{self._anonymous}"
            self._anonymous += 1
        first = self.trees.get(tid)
        if first is not None:
            self.fail(
                where,
                el.line,
                f"a second <BehaviorTree ID={tid!r}> (the first is at {first.where} "
                f"line {first.line})",
            )
        else:
            self.trees[tid] = el

    def _models(self, el: XmlElement) -> None:
        for model in el.children:
            if model.tag in MODEL_KINDS and model.attrs.get("ID"):
                self.models.setdefault(model.attrs["ID"], model)

    def _include(
        self, el: XmlElement, where: str, folder: Path | None, chain: tuple[Path, ...]
    ) -> None:
        if "ros_pkg" in el.attrs:
            self.fail(
                where,
                el.line,
                f"<include ros_pkg={el.attrs['ros_pkg']!r}>: btcap does not look up ROS "
                f"packages; give the path relative to this file instead",
            )
            return
        rel = el.attrs.get("path")
        if not rel:
            self.fail(where, el.line, "<include> without a path")
            return
        if folder is None and not Path(rel).is_absolute():
            self.fail(
                where,
                el.line,
                f"<include path={rel!r}>: a tree read from text has no directory to "
                f"resolve it in; load the file, or pass base=",
            )
            return
        path = Path(rel) if Path(rel).is_absolute() else (folder or Path()) / rel
        key = path.resolve()
        if key in chain:
            names = " -> ".join(str(p) for p in (*chain[chain.index(key) :], key))
            self.fail(where, el.line, f"<include path={rel!r}>: includes itself ({names})")
            return
        if not path.is_file():
            self.fail(where, el.line, f"<include path={rel!r}>: no such file {path}")
            return
        try:
            inner = read_xml(read_bytes(path), str(path))
        except TreeFileError as exc:
            for problem in exc.problems:
                self.fail(str(path), 0, problem.removeprefix(f"{path}: "))
            return
        if self.root(inner, str(path)):
            self.read(inner, str(path), path.parent, (*chain, key))
